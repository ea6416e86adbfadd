#include "textured_quads.hpp"

#include <cstddef>

namespace ultrasim::render::detail {

TexturedQuads::TexturedQuads() : vertices_(GL_ARRAY_BUFFER) {
  glGenVertexArrays(1, &vao_);
  glBindVertexArray(vao_);
  vertices_.reserve(sizeof(TexturedVertex) * 4 * kSlots);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(TexturedVertex),
                        reinterpret_cast<const void*>(offsetof(TexturedVertex, x)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(TexturedVertex),
                        reinterpret_cast<const void*>(offsetof(TexturedVertex, u)));
  glBindVertexArray(0);
}

TexturedQuads::~TexturedQuads() {
  glDeleteVertexArrays(1, &vao_);
}

void TexturedQuads::draw(int slot, const std::array<Vec3, 4>& corners,
                         const std::array<std::array<float, 2>, 4>& uvs) {
  std::array<TexturedVertex, 4> quad{};
  for (int i = 0; i < 4; ++i) {
    quad[i] = {corners[i][0], corners[i][1], corners[i][2], uvs[i][0], uvs[i][1]};
  }
  glBindVertexArray(vao_);
  vertices_.bind();
  glBufferSubData(GL_ARRAY_BUFFER, static_cast<GLintptr>(sizeof(quad) * slot), sizeof(quad),
                  quad.data());
  glDrawArrays(GL_TRIANGLE_FAN, slot * 4, 4);
  glBindVertexArray(0);
}

}  // namespace ultrasim::render::detail
