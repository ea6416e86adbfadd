#pragma once

#include <cstdint>
#include <vector>

namespace ultrasim::render {

// An 8-bit RGBA picture in memory: rows top first, 4 bytes per pixel, no row padding.
// rgba.size() == width * height * 4 whenever the image is non-empty.
struct RgbaImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;

  // Pointer to the pixel at column x, row y (row 0 at the top). No bounds check.
  const std::uint8_t* at(int x, int y) const {
    return rgba.data() + (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                          static_cast<std::size_t>(x)) *
                             4;
  }
};

}  // namespace ultrasim::render
