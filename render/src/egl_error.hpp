#pragma once

// Names of EGL and GL error codes for DisplayError messages. Internal to render/.

namespace ultrasim::render::detail {

// "EGL_NOT_INITIALIZED" etc.; "unknown EGL error" for codes EGL does not define.
const char* egl_error_name(int code);
// "GL_INVALID_ENUM", "GL_FRAMEBUFFER_UNSUPPORTED" etc.
const char* gl_error_name(unsigned code);

}  // namespace ultrasim::render::detail
