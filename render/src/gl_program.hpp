#pragma once

// Compiling and linking GLSL ES 3.00 programs at start-up. Internal to render/.

#include <GLES3/gl3.h>

namespace ultrasim::render::detail {

// Compiles the two shaders and links them into a program. name labels error messages.
// Throws std::runtime_error carrying the shader or program info log on failure. Render thread.
GLuint build_program(const char* name, const char* vertex_source, const char* fragment_source);

// A uniform's location; throws std::runtime_error when the linked program lacks it (a misspelt
// name would otherwise silently do nothing).
GLint uniform_location(GLuint program, const char* program_name, const char* uniform);

}  // namespace ultrasim::render::detail
