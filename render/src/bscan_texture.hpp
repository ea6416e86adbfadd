#pragma once

// The B-scan as a GL texture, refreshed every frame. Internal to render/.

#include <GLES3/gl3.h>

#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::render::detail {

// True when the view holds a whole image: positive sizes, at least width × height pixels and a
// positive, finite physical extent. Anything else is shown as "no image", never sampled.
bool is_drawable(const BscanView& bscan);

// One GL_R8 texture, linear filtering, clamped at the edges. update() reallocates the texture
// storage (glTexImage2D) only when the image size changes, otherwise overwrites it in place
// (glTexSubImage2D). Render thread only.
class BscanTexture {
 public:
  BscanTexture();
  ~BscanTexture();
  BscanTexture(const BscanTexture&) = delete;
  BscanTexture& operator=(const BscanTexture&) = delete;

  // Uploads the pixels of a drawable view (see is_drawable); returns false and leaves the texture
  // as it was for anything else.
  bool update(const BscanView& bscan);
  void bind() const;
  // True once a frame has been uploaded.
  bool has_image() const { return width_px_ > 0; }

 private:
  GLuint id_ = 0;
  int width_px_ = 0;
  int height_px_ = 0;
};

}  // namespace ultrasim::render::detail
