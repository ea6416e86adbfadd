#include "ultrasim/render/offscreen_display.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>

#include "egl_error.hpp"
#include "ultrasim/render/display_error.hpp"

namespace ultrasim::render {
namespace {

constexpr int kMaxSidePx = 16384;

[[noreturn]] void throw_egl(const char* call, const char* hint = nullptr) {
  std::string message = std::string(call) + " failed: " + detail::egl_error_name(eglGetError());
  if (hint != nullptr) message += std::string(" (") + hint + ")";
  throw DisplayError(message);
}

[[noreturn]] void throw_gl(const char* call, unsigned code) {
  throw DisplayError(std::string(call) + " failed: " + detail::gl_error_name(code));
}

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t name_len = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += name_len) {
    const bool starts = p == list || p[-1] == ' ';
    const bool ends = p[name_len] == '\0' || p[name_len] == ' ';
    if (starts && ends) return true;
  }
  return false;
}

// The surfaceless EGLDisplay is one per process (EGL hands back the same handle for the same
// platform), and eglTerminate on it would pull the rug from under every other OffscreenDisplay.
// So it is initialised by the first user and terminated by the last.
class SharedEglDisplay {
 public:
  static EGLDisplay acquire() {
    const std::lock_guard lock(mutex_);
    if (users_ == 0) display_ = open();
    ++users_;
    return display_;
  }

  static void release() {
    const std::lock_guard lock(mutex_);
    if (users_ == 0) return;
    if (--users_ == 0) {
      eglTerminate(display_);
      // Frees this thread's EGL state; no other OffscreenDisplay is left to need it.
      eglReleaseThread();
      display_ = EGL_NO_DISPLAY;
    }
  }

 private:
  static EGLDisplay open() {
    const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
      throw DisplayError(
          "eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS) lacks EGL_MESA_platform_surfaceless "
          "(is libegl-mesa0 installed?)");
    }
    const auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_platform_display == nullptr) {
      throw DisplayError("eglGetProcAddress(eglGetPlatformDisplayEXT) returned null");
    }
    const EGLDisplay display =
        get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (display == EGL_NO_DISPLAY) throw_egl("eglGetPlatformDisplayEXT(SURFACELESS_MESA)");
    EGLint major = 0;
    EGLint minor = 0;
    if (eglInitialize(display, &major, &minor) != EGL_TRUE) {
      throw_egl("eglInitialize", "is libgl1-mesa-dri installed?");
    }
    return display;
  }

  static inline std::mutex mutex_;
  static inline int users_ = 0;
  static inline EGLDisplay display_ = EGL_NO_DISPLAY;
};

}  // namespace

struct OffscreenDisplay::Impl {
  int width_px = 0;
  int height_px = 0;
  int msaa_samples = 0;
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  // Single-sample target: drawn into directly without MSAA, the resolve target with it.
  GLuint fbo = 0;
  GLuint colour_rb = 0;
  GLuint depth_rb = 0;
  // Multisampled draw target (0 when MSAA is off).
  GLuint msaa_fbo = 0;
  GLuint msaa_colour_rb = 0;
  GLuint msaa_depth_rb = 0;

  void create_context() {
    display = SharedEglDisplay::acquire();
    if (eglBindAPI(EGL_OPENGL_ES_API) != EGL_TRUE) throw_egl("eglBindAPI(EGL_OPENGL_ES_API)");

    // Surface type 0: we never make a surface, only render into framebuffer objects.
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT, EGL_SURFACE_TYPE,
                                        0, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint config_count = 0;
    if (eglChooseConfig(display, config_attributes, &config, 1, &config_count) != EGL_TRUE) {
      throw_egl("eglChooseConfig(EGL_OPENGL_ES3_BIT)");
    }
    if (config_count == 0) {
      if (!has_extension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_no_config_context")) {
        throw DisplayError("eglChooseConfig(EGL_OPENGL_ES3_BIT) found no config: no GLES 3 driver");
      }
      config = EGL_NO_CONFIG_KHR;
    }
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 0,
                                         EGL_NONE};
    context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
    if (context == EGL_NO_CONTEXT) throw_egl("eglCreateContext(GLES 3.0)");
    if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
      throw_egl("eglMakeCurrent(EGL_NO_SURFACE)", "needs EGL_KHR_surfaceless_context");
    }
  }

  static void allocate_renderbuffer(GLuint rb, int samples, GLenum format, int w, int h) {
    glBindRenderbuffer(GL_RENDERBUFFER, rb);
    if (samples > 0) {
      glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, format, w, h);
    } else {
      glRenderbufferStorage(GL_RENDERBUFFER, format, w, h);
    }
    if (const GLenum error = glGetError(); error != GL_NO_ERROR) {
      throw_gl("glRenderbufferStorage", error);
    }
  }

  static void check_complete(const char* which) {
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) throw_gl(which, status);
  }

  void create_framebuffers(int requested_samples) {
    GLint max_renderbuffer_px = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_renderbuffer_px);
    if (width_px > max_renderbuffer_px || height_px > max_renderbuffer_px) {
      throw DisplayError("framebuffer " + std::to_string(width_px) + "x" +
                         std::to_string(height_px) + " exceeds GL_MAX_RENDERBUFFER_SIZE " +
                         std::to_string(max_renderbuffer_px));
    }
    GLint max_samples = 0;
    glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    msaa_samples = std::clamp(requested_samples, 0, static_cast<int>(max_samples));
    if (msaa_samples == 1) msaa_samples = 0;

    glGenFramebuffers(1, &fbo);
    glGenRenderbuffers(1, &colour_rb);
    glGenRenderbuffers(1, &depth_rb);
    allocate_renderbuffer(colour_rb, 0, GL_RGBA8, width_px, height_px);
    allocate_renderbuffer(depth_rb, 0, GL_DEPTH_COMPONENT24, width_px, height_px);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour_rb);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
    check_complete("glCheckFramebufferStatus(offscreen FBO)");

    if (msaa_samples > 0) {
      glGenFramebuffers(1, &msaa_fbo);
      glGenRenderbuffers(1, &msaa_colour_rb);
      glGenRenderbuffers(1, &msaa_depth_rb);
      allocate_renderbuffer(msaa_colour_rb, msaa_samples, GL_RGBA8, width_px, height_px);
      allocate_renderbuffer(msaa_depth_rb, msaa_samples, GL_DEPTH_COMPONENT24, width_px, height_px);
      glBindFramebuffer(GL_FRAMEBUFFER, msaa_fbo);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                msaa_colour_rb);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                                msaa_depth_rb);
      check_complete("glCheckFramebufferStatus(multisampled FBO)");
    }
    glBindFramebuffer(GL_FRAMEBUFFER, draw_fbo());
  }

  GLuint draw_fbo() const { return msaa_fbo != 0 ? msaa_fbo : fbo; }

  void make_current() {
    if (eglGetCurrentContext() != context) {
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context);
    }
  }

  // Safe on a partly constructed Impl: the constructor calls it before rethrowing.
  void destroy() {
    if (context != EGL_NO_CONTEXT) {
      make_current();
      const GLuint framebuffers[] = {fbo, msaa_fbo};
      const GLuint renderbuffers[] = {colour_rb, depth_rb, msaa_colour_rb, msaa_depth_rb};
      glDeleteFramebuffers(2, framebuffers);
      glDeleteRenderbuffers(4, renderbuffers);
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display, context);
      context = EGL_NO_CONTEXT;
    }
    if (display != EGL_NO_DISPLAY) {
      SharedEglDisplay::release();
      display = EGL_NO_DISPLAY;
    }
  }
};

OffscreenDisplay::OffscreenDisplay(const DisplaySettings& settings, const OffscreenOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (settings.width_px < 1 || settings.height_px < 1 || settings.width_px > kMaxSidePx ||
      settings.height_px > kMaxSidePx) {
    throw std::invalid_argument("OffscreenDisplay: size " + std::to_string(settings.width_px) +
                                "x" + std::to_string(settings.height_px) +
                                " outside 1..16384 pixels");
  }
  impl_->width_px = settings.width_px;
  impl_->height_px = settings.height_px;
  try {
    impl_->create_context();
    impl_->create_framebuffers(options.msaa_samples);
  } catch (...) {
    impl_->destroy();
    throw;
  }
}

OffscreenDisplay::~OffscreenDisplay() {
  impl_->destroy();
}

int OffscreenDisplay::width_px() const {
  return impl_->width_px;
}
int OffscreenDisplay::height_px() const {
  return impl_->height_px;
}
int OffscreenDisplay::msaa_samples() const {
  return impl_->msaa_samples;
}

const char* OffscreenDisplay::renderer_name() const {
  impl_->make_current();
  return reinterpret_cast<const char*>(glGetString(GL_RENDERER));
}

void OffscreenDisplay::begin_frame() {
  impl_->make_current();
  glBindFramebuffer(GL_FRAMEBUFFER, impl_->draw_fbo());
  glViewport(0, 0, impl_->width_px, impl_->height_px);
}

void OffscreenDisplay::end_frame() {
  if (impl_->msaa_fbo != 0) {
    // Resolve the samples into the single-sample target that read_pixels_into reads.
    glBindFramebuffer(GL_READ_FRAMEBUFFER, impl_->msaa_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, impl_->fbo);
    glBlitFramebuffer(0, 0, impl_->width_px, impl_->height_px, 0, 0, impl_->width_px,
                      impl_->height_px, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    // The multisampled depth is not needed past this point; saying so spares tiled GPUs a store.
    glBindFramebuffer(GL_FRAMEBUFFER, impl_->msaa_fbo);
    const GLenum discard[] = {GL_DEPTH_ATTACHMENT};
    glInvalidateFramebuffer(GL_FRAMEBUFFER, 1, discard);
  }
  // There is no scan-out to wait for: the frame counts as shown once it is drawn. Waiting here
  // puts the rasteriser's work (deferred until a flush on llvmpipe) in this frame's time, where
  // a display's page flip would put it, and makes end_frame's return the frame's presentation.
  glFinish();
}

void OffscreenDisplay::read_pixels_into(RgbaImage& out) {
  impl_->make_current();
  const int w = impl_->width_px;
  const int h = impl_->height_px;
  const std::size_t row_bytes = static_cast<std::size_t>(w) * 4;
  out.width = w;
  out.height = h;
  out.rgba.resize(row_bytes * static_cast<std::size_t>(h));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, impl_->fbo);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  glBindFramebuffer(GL_FRAMEBUFFER, impl_->draw_fbo());
  if (const GLenum error = glGetError(); error != GL_NO_ERROR)
    throw_gl("glReadPixels (or an earlier GL call)", error);
  // GL's row 0 is the bottom one; RgbaImage's is the top.
  for (int top = 0, bottom = h - 1; top < bottom; ++top, --bottom) {
    std::swap_ranges(out.rgba.begin() + static_cast<std::ptrdiff_t>(row_bytes * top),
                     out.rgba.begin() + static_cast<std::ptrdiff_t>(row_bytes * (top + 1)),
                     out.rgba.begin() + static_cast<std::ptrdiff_t>(row_bytes * bottom));
  }
}

}  // namespace ultrasim::render
