#pragma once

// Quads textured with the B-scan: one in 3D (the image plane under the probe), one in 2D (the
// panel). Internal to render/.

#include <GLES3/gl3.h>

#include <array>

#include "mat4.hpp"
#include "stream_buffer.hpp"

namespace ultrasim::render::detail {

struct TexturedVertex {
  float x, y, z;
  float u, v;
};

// Render thread only; no allocation after construction.
class TexturedQuads {
 public:
  static constexpr int kSlots = 2;

  TexturedQuads();
  ~TexturedQuads();
  TexturedQuads(const TexturedQuads&) = delete;
  TexturedQuads& operator=(const TexturedQuads&) = delete;

  // Draws the quad with corners in order around its edge (a triangle fan) and their texture
  // coordinates, using the program and texture bound by the caller. slot keeps the two quads
  // in separate parts of the buffer.
  void draw(int slot, const std::array<Vec3, 4>& corners,
            const std::array<std::array<float, 2>, 4>& uvs);

 private:
  StreamBuffer vertices_;
  GLuint vao_ = 0;
};

}  // namespace ultrasim::render::detail
