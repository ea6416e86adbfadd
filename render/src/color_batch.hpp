#pragma once

// Vertex-coloured triangles and lines gathered on the CPU during a frame and drawn with two
// draw calls. Used for the probe, rings and boxes in 3D and for every panel, tick and glyph of
// the 2D overlay (in pixel coordinates, z = 0). Internal to render/.

#include <GLES3/gl3.h>

#include <cstdint>
#include <string_view>
#include <vector>

#include "mat4.hpp"
#include "stream_buffer.hpp"
#include "theme.hpp"

namespace ultrasim::render::detail {

struct ColorVertex {
  float x, y, z;
  Rgba8 colour;
};

// Render thread only. clear() keeps capacity, so after the first frames building a batch of
// the same size does not allocate.
class ColorBatch {
 public:
  ColorBatch();
  ~ColorBatch();
  ColorBatch(const ColorBatch&) = delete;
  ColorBatch& operator=(const ColorBatch&) = delete;

  void clear();
  bool empty() const { return triangles_.empty() && lines_.empty(); }

  void triangle(const Vec3& a, const Vec3& b, const Vec3& c, Rgba8 colour);
  // Quad a-b-c-d (in order around its edge) as two triangles.
  void quad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, Rgba8 colour);
  void line(const Vec3& a, const Vec3& b, Rgba8 colour);

  // 2D helpers, in pixels (origin top-left, y down).
  void fill_rect(float x, float y, float w, float h, Rgba8 colour);
  // Rectangle outline of the given thickness, drawn inside the rectangle.
  void outline_rect(float x, float y, float w, float h, float thickness, Rgba8 colour);
  // Horizontal gradient from left to right colour.
  void gradient_rect(float x, float y, float w, float h, Rgba8 left, Rgba8 right);
  // Vertical gradient from top to bottom colour.
  void vertical_gradient_rect(float x, float y, float w, float h, Rgba8 top, Rgba8 bottom);
  // A straight stroke of the given width (a thin quad), for lines that need a set thickness.
  void stroke(float x0, float y0, float x1, float y1, float width, Rgba8 colour);
  // Text in the 5×7 dot font with its top-left corner at (x, y); dot_px is the size of one dot.
  // Returns the width drawn, in pixels.
  float text(float x, float y, float dot_px, std::string_view text, Rgba8 colour);

  // Uploads the batch and draws its triangles, then its lines, with the program bound by the
  // caller (attribute 0 = position, 1 = normalised RGBA).
  void draw();

 private:
  std::vector<ColorVertex> triangles_;
  std::vector<ColorVertex> lines_;
  StreamBuffer vertices_;
  GLuint vao_ = 0;
};

}  // namespace ultrasim::render::detail
