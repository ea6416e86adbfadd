#pragma once

#include <cstdint>
#include <filesystem>
#include <span>

#include "ultrasim/render/rgba_image.hpp"

namespace ultrasim::render {

// Writes image as an 8-bit RGBA PNG (rows top first, as stored). Any thread; allocates (libpng).
// Throws std::runtime_error naming the path and the cause (e.g. "No such file or directory") when
// the file cannot be written, and std::invalid_argument for an empty or inconsistent image.
void write_png(const std::filesystem::path& path, const RgbaImage& image);

// Writes width_px × height_px grey levels (row-major, row 0 at the top) as an 8-bit greyscale
// PNG, e.g. a B-scan. Same threading, allocation and errors as write_png.
void write_png_grey(const std::filesystem::path& path, std::span<const std::uint8_t> grey,
                    int width_px, int height_px);

}  // namespace ultrasim::render
