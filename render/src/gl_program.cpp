#include "gl_program.hpp"

#include <stdexcept>
#include <string>

namespace ultrasim::render::detail {
namespace {

std::string shader_log(GLuint shader) {
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(length > 0 ? length : 1), '\0');
  glGetShaderInfoLog(shader, static_cast<GLsizei>(log.size()), nullptr, log.data());
  return log.c_str();
}

std::string program_log(GLuint program) {
  GLint length = 0;
  glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(length > 0 ? length : 1), '\0');
  glGetProgramInfoLog(program, static_cast<GLsizei>(log.size()), nullptr, log.data());
  return log.c_str();
}

GLuint compile(const char* name, GLenum stage, const char* source) {
  const GLuint shader = glCreateShader(stage);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = shader_log(shader);
    glDeleteShader(shader);
    throw std::runtime_error(std::string("compiling the ") +
                             (stage == GL_VERTEX_SHADER ? "vertex" : "fragment") + " shader of '" +
                             name + "' failed: " + log);
  }
  return shader;
}

}  // namespace

GLuint build_program(const char* name, const char* vertex_source, const char* fragment_source) {
  const GLuint vertex = compile(name, GL_VERTEX_SHADER, vertex_source);
  GLuint fragment = 0;
  try {
    fragment = compile(name, GL_FRAGMENT_SHADER, fragment_source);
  } catch (...) {
    glDeleteShader(vertex);
    throw;
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, vertex);
  glAttachShader(program, fragment);
  glLinkProgram(program);
  // The program keeps what it needs; the shader objects can go now.
  glDeleteShader(vertex);
  glDeleteShader(fragment);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = program_log(program);
    glDeleteProgram(program);
    throw std::runtime_error(std::string("linking program '") + name + "' failed: " + log);
  }
  return program;
}

GLint uniform_location(GLuint program, const char* program_name, const char* uniform) {
  const GLint location = glGetUniformLocation(program, uniform);
  if (location < 0) {
    throw std::runtime_error(std::string("program '") + program_name + "' has no uniform '" +
                             uniform + "'");
  }
  return location;
}

}  // namespace ultrasim::render::detail
