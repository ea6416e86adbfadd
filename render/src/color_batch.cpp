#include "color_batch.hpp"

#include <cmath>
#include <cstddef>

#include "bitmap_font.hpp"

namespace ultrasim::render::detail {

ColorBatch::ColorBatch() : vertices_(GL_ARRAY_BUFFER) {
  glGenVertexArrays(1, &vao_);
  glBindVertexArray(vao_);
  vertices_.bind();
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(ColorVertex),
                        reinterpret_cast<const void*>(offsetof(ColorVertex, x)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(ColorVertex),
                        reinterpret_cast<const void*>(offsetof(ColorVertex, colour)));
  glBindVertexArray(0);
  triangles_.reserve(4096);
  lines_.reserve(1024);
}

ColorBatch::~ColorBatch() {
  glDeleteVertexArrays(1, &vao_);
}

void ColorBatch::clear() {
  triangles_.clear();
  lines_.clear();
}

void ColorBatch::triangle(const Vec3& a, const Vec3& b, const Vec3& c, Rgba8 colour) {
  triangles_.push_back({a[0], a[1], a[2], colour});
  triangles_.push_back({b[0], b[1], b[2], colour});
  triangles_.push_back({c[0], c[1], c[2], colour});
}

void ColorBatch::quad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, Rgba8 colour) {
  triangle(a, b, c, colour);
  triangle(a, c, d, colour);
}

void ColorBatch::line(const Vec3& a, const Vec3& b, Rgba8 colour) {
  lines_.push_back({a[0], a[1], a[2], colour});
  lines_.push_back({b[0], b[1], b[2], colour});
}

void ColorBatch::fill_rect(float x, float y, float w, float h, Rgba8 colour) {
  if (w <= 0.0f || h <= 0.0f) return;
  quad({x, y, 0}, {x + w, y, 0}, {x + w, y + h, 0}, {x, y + h, 0}, colour);
}

void ColorBatch::outline_rect(float x, float y, float w, float h, float thickness, Rgba8 colour) {
  fill_rect(x, y, w, thickness, colour);
  fill_rect(x, y + h - thickness, w, thickness, colour);
  fill_rect(x, y + thickness, thickness, h - 2 * thickness, colour);
  fill_rect(x + w - thickness, y + thickness, thickness, h - 2 * thickness, colour);
}

void ColorBatch::gradient_rect(float x, float y, float w, float h, Rgba8 left, Rgba8 right) {
  if (w <= 0.0f || h <= 0.0f) return;
  triangles_.push_back({x, y, 0, left});
  triangles_.push_back({x + w, y, 0, right});
  triangles_.push_back({x + w, y + h, 0, right});
  triangles_.push_back({x, y, 0, left});
  triangles_.push_back({x + w, y + h, 0, right});
  triangles_.push_back({x, y + h, 0, left});
}

void ColorBatch::vertical_gradient_rect(float x, float y, float w, float h, Rgba8 top,
                                        Rgba8 bottom) {
  if (w <= 0.0f || h <= 0.0f) return;
  triangles_.push_back({x, y, 0, top});
  triangles_.push_back({x + w, y, 0, top});
  triangles_.push_back({x + w, y + h, 0, bottom});
  triangles_.push_back({x, y, 0, top});
  triangles_.push_back({x + w, y + h, 0, bottom});
  triangles_.push_back({x, y + h, 0, bottom});
}

void ColorBatch::stroke(float x0, float y0, float x1, float y1, float width, Rgba8 colour) {
  const float dx = x1 - x0;
  const float dy = y1 - y0;
  const float len = std::sqrt(dx * dx + dy * dy);
  if (len <= 0.0f) return;
  // Half-width offset perpendicular to the stroke.
  const float nx = -dy / len * width * 0.5f;
  const float ny = dx / len * width * 0.5f;
  quad({x0 + nx, y0 + ny, 0}, {x1 + nx, y1 + ny, 0}, {x1 - nx, y1 - ny, 0}, {x0 - nx, y0 - ny, 0},
       colour);
}

float ColorBatch::text(float x, float y, float dot_px, std::string_view text, Rgba8 colour) {
  float pen_x = x;
  for (const char c : text) {
    const auto& rows = glyph_rows(c);
    for (int row = 0; row < kGlyphHeightDots; ++row) {
      // Runs of lit dots become one quad each: fewer vertices than one quad per dot.
      int col = 0;
      while (col < kGlyphWidthDots) {
        const auto lit = [&](int k) { return (rows[row] >> (kGlyphWidthDots - 1 - k)) & 1; };
        if (!lit(col)) {
          ++col;
          continue;
        }
        const int start = col;
        while (col < kGlyphWidthDots && lit(col)) ++col;
        fill_rect(pen_x + static_cast<float>(start) * dot_px, y + static_cast<float>(row) * dot_px,
                  static_cast<float>(col - start) * dot_px, dot_px, colour);
      }
    }
    pen_x += kGlyphAdvanceDots * dot_px;
  }
  return static_cast<float>(text_width_dots(text)) * dot_px;
}

void ColorBatch::draw() {
  if (empty()) return;
  const std::size_t triangle_bytes = triangles_.size() * sizeof(ColorVertex);
  const std::size_t line_bytes = lines_.size() * sizeof(ColorVertex);
  glBindVertexArray(vao_);
  // One buffer, triangles first then lines.
  vertices_.reserve(triangle_bytes + line_bytes);
  if (triangle_bytes > 0) {
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(triangle_bytes), triangles_.data());
  }
  if (line_bytes > 0) {
    glBufferSubData(GL_ARRAY_BUFFER, static_cast<GLintptr>(triangle_bytes),
                    static_cast<GLsizeiptr>(line_bytes), lines_.data());
  }
  if (!triangles_.empty()) {
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(triangles_.size()));
  }
  if (!lines_.empty()) {
    glDrawArrays(GL_LINES, static_cast<GLint>(triangles_.size()),
                 static_cast<GLsizei>(lines_.size()));
  }
  glBindVertexArray(0);
}

}  // namespace ultrasim::render::detail
