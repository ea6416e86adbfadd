#include "bscan_texture.hpp"

#include <cmath>
#include <cstddef>

namespace ultrasim::render::detail {

bool is_drawable(const BscanView& bscan) {
  if (bscan.width_px <= 0 || bscan.height_px <= 0) return false;
  const std::size_t needed =
      static_cast<std::size_t>(bscan.width_px) * static_cast<std::size_t>(bscan.height_px);
  return bscan.pixels.size() >= needed && std::isfinite(bscan.width_mm) &&
         std::isfinite(bscan.depth_mm) && bscan.width_mm > 0.0f && bscan.depth_mm > 0.0f;
}

BscanTexture::BscanTexture() {
  glGenTextures(1, &id_);
  glBindTexture(GL_TEXTURE_2D, id_);
  // Linear: the panel magnifies the B-scan, and nearest sampling would show blocky speckle.
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

BscanTexture::~BscanTexture() {
  glDeleteTextures(1, &id_);
}

bool BscanTexture::update(const BscanView& bscan) {
  if (!is_drawable(bscan)) return false;
  glBindTexture(GL_TEXTURE_2D, id_);
  // Rows of one-byte pixels are not 4-byte aligned in general.
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  if (bscan.width_px != width_px_ || bscan.height_px != height_px_) {
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, bscan.width_px, bscan.height_px, 0, GL_RED,
                 GL_UNSIGNED_BYTE, bscan.pixels.data());
    width_px_ = bscan.width_px;
    height_px_ = bscan.height_px;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, bscan.width_px, bscan.height_px, GL_RED,
                    GL_UNSIGNED_BYTE, bscan.pixels.data());
  }
  return true;
}

void BscanTexture::bind() const {
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, id_);
}

}  // namespace ultrasim::render::detail
