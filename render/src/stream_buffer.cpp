#include "stream_buffer.hpp"

namespace ultrasim::render::detail {

StreamBuffer::StreamBuffer(GLenum target) : target_(target) {
  glGenBuffers(1, &id_);
}

StreamBuffer::~StreamBuffer() {
  glDeleteBuffers(1, &id_);
}

void StreamBuffer::reserve(std::size_t size_bytes) {
  glBindBuffer(target_, id_);
  if (size_bytes > capacity_bytes_) {
    capacity_bytes_ = size_bytes + size_bytes / 2;
    glBufferData(target_, static_cast<GLsizeiptr>(capacity_bytes_), nullptr, GL_DYNAMIC_DRAW);
  }
}

void StreamBuffer::upload(const void* data, std::size_t size_bytes) {
  reserve(size_bytes);
  if (size_bytes == 0) return;
  glBufferSubData(target_, 0, static_cast<GLsizeiptr>(size_bytes), data);
}

}  // namespace ultrasim::render::detail
