#include "ultrasim/render/png_writer.hpp"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>

namespace ultrasim::render {
namespace {

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};

// libpng's simplified API does the setjmp/longjmp error handling inside libpng, so no C error
// unwinds through our C++ frames; failures come back as a return value and image.message.
void write_png_file(const std::filesystem::path& path, const std::uint8_t* pixels, int width_px,
                    int height_px, png_uint_32 format, int bytes_per_pixel) {
  errno = 0;
  const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.c_str(), "wb"));
  if (!file) {
    throw std::runtime_error("cannot write PNG '" + path.string() + "': " + std::strerror(errno));
  }
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width_px);
  image.height = static_cast<png_uint_32>(height_px);
  image.format = format;
  const png_int_32 row_stride = width_px * bytes_per_pixel;
  const int ok = png_image_write_to_stdio(&image, file.get(), 0, pixels, row_stride, nullptr);
  const std::string libpng_message = image.message;
  png_image_free(&image);
  if (ok == 0) {
    throw std::runtime_error("cannot write PNG '" + path.string() + "': " + libpng_message);
  }
  if (std::fflush(file.get()) != 0 || std::ferror(file.get()) != 0) {
    throw std::runtime_error("cannot write PNG '" + path.string() + "': " + std::strerror(errno));
  }
}

void check_size(const char* function, std::size_t bytes, int width_px, int height_px,
                int bytes_per_pixel) {
  if (width_px < 1 || height_px < 1 ||
      bytes != static_cast<std::size_t>(width_px) * static_cast<std::size_t>(height_px) *
                   static_cast<std::size_t>(bytes_per_pixel)) {
    throw std::invalid_argument(std::string(function) + ": " + std::to_string(bytes) +
                                " bytes do not make a " + std::to_string(width_px) + "x" +
                                std::to_string(height_px) + " image");
  }
}

}  // namespace

void write_png(const std::filesystem::path& path, const RgbaImage& image) {
  check_size("write_png", image.rgba.size(), image.width, image.height, 4);
  write_png_file(path, image.rgba.data(), image.width, image.height, PNG_FORMAT_RGBA, 4);
}

void write_png_grey(const std::filesystem::path& path, std::span<const std::uint8_t> grey,
                    int width_px, int height_px) {
  check_size("write_png_grey", grey.size(), width_px, height_px, 1);
  write_png_file(path, grey.data(), width_px, height_px, PNG_FORMAT_GRAY, 1);
}

}  // namespace ultrasim::render
