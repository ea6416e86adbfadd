#pragma once

// A GL buffer object refilled every frame. Internal to render/.

#include <GLES3/gl3.h>

#include <cstddef>

namespace ultrasim::render::detail {

// Owns one buffer object. upload() reallocates the GPU storage (glBufferData) only when the data
// outgrows it, with 50 % headroom so slowly growing data does not reallocate every frame;
// otherwise it overwrites in place (glBufferSubData). Render thread only.
class StreamBuffer {
 public:
  explicit StreamBuffer(GLenum target);
  ~StreamBuffer();
  StreamBuffer(const StreamBuffer&) = delete;
  StreamBuffer& operator=(const StreamBuffer&) = delete;

  // Binds the buffer to its target and makes its storage hold at least size_bytes; the contents
  // are undefined after a grow. For filling the buffer in parts with glBufferSubData.
  void reserve(std::size_t size_bytes);
  // Binds the buffer to its target and copies size_bytes from data into it.
  void upload(const void* data, std::size_t size_bytes);
  void bind() const { glBindBuffer(target_, id_); }
  GLuint id() const { return id_; }

 private:
  GLenum target_;
  GLuint id_ = 0;
  std::size_t capacity_bytes_ = 0;
};

}  // namespace ultrasim::render::detail
