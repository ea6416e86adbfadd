#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "ultrasim/render/rgba_image.hpp"

namespace ultrasim::render {

// Writes image as an 8-bit RGBA PNG (rows top first, as stored). Any thread; allocates (libpng).
// Throws std::runtime_error naming the path and the cause (e.g. "No such file or directory") when
// the file cannot be written, and std::invalid_argument for an empty or inconsistent image.
void write_png(const std::filesystem::path& path, const RgbaImage& image);

// A PNG text field (a tEXt chunk): a keyword of 1–79 Latin-1 characters and its text.
struct PngText {
  std::string key;
  std::string value;
};

// Writes width_px × height_px grey levels (row-major, row 0 at the top) as an 8-bit greyscale
// PNG, e.g. a B-scan, with `text` as tEXt chunks (what an image viewer shows as its properties).
// Same threading, allocation and errors as write_png; std::invalid_argument for a bad keyword.
void write_png_grey(const std::filesystem::path& path, std::span<const std::uint8_t> grey,
                    int width_px, int height_px, std::span<const PngText> text = {});

// The tEXt fields of a PNG file, in file order. Throws std::runtime_error naming the path when it
// cannot be read or is not a PNG. Allocates.
std::vector<PngText> read_png_text(const std::filesystem::path& path);

}  // namespace ultrasim::render
