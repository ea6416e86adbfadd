#include "ultrasim/render/png_writer.hpp"

#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
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
void append_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(v >> shift));
}

std::uint32_t read_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         p[3];
}

// A tEXt chunk: length, type, keyword NUL text, CRC over type and data (PNG spec §5.3).
std::vector<std::uint8_t> text_chunk(const PngText& t) {
  if (t.key.empty() || t.key.size() > 79 || t.key.find('\0') != std::string::npos ||
      t.value.find('\0') != std::string::npos) {
    throw std::invalid_argument("PNG text: keyword '" + t.key +
                                "' must be 1-79 characters and neither may hold NUL");
  }
  std::vector<std::uint8_t> body = {'t', 'E', 'X', 't'};
  body.insert(body.end(), t.key.begin(), t.key.end());
  body.push_back(0);
  body.insert(body.end(), t.value.begin(), t.value.end());
  std::vector<std::uint8_t> chunk;
  append_u32(chunk, static_cast<std::uint32_t>(body.size() - 4));
  chunk.insert(chunk.end(), body.begin(), body.end());
  append_u32(chunk,
             static_cast<std::uint32_t>(crc32(0L, body.data(), static_cast<uInt>(body.size()))));
  return chunk;
}

// libpng's simplified API does the setjmp/longjmp error handling inside libpng, so no C error
// unwinds through our C++ frames; failures come back as a return value and image.message. It
// writes to memory; text chunks go in before the IEND chunk, which closes every PNG.
void write_png_file(const std::filesystem::path& path, const std::uint8_t* pixels, int width_px,
                    int height_px, png_uint_32 format, int bytes_per_pixel,
                    std::span<const PngText> text = {}) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width_px);
  image.height = static_cast<png_uint_32>(height_px);
  image.format = format;
  const png_int_32 row_stride = width_px * bytes_per_pixel;
  png_alloc_size_t size = 0;
  int ok = png_image_write_to_memory(&image, nullptr, &size, 0, pixels, row_stride, nullptr);
  std::vector<std::uint8_t> bytes(size);
  if (ok != 0) {
    ok = png_image_write_to_memory(&image, bytes.data(), &size, 0, pixels, row_stride, nullptr);
  }
  const std::string libpng_message = image.message;
  png_image_free(&image);
  if (ok == 0 || size < 12) {
    throw std::runtime_error("cannot write PNG '" + path.string() + "': " + libpng_message);
  }
  bytes.resize(size);
  std::vector<std::uint8_t> chunks;
  for (const auto& t : text) {
    const auto chunk = text_chunk(t);
    chunks.insert(chunks.end(), chunk.begin(), chunk.end());
  }
  bytes.insert(bytes.end() - 12, chunks.begin(), chunks.end());  // IEND is the last 12 bytes
  errno = 0;
  const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.c_str(), "wb"));
  if (!file) {
    throw std::runtime_error("cannot write PNG '" + path.string() + "': " + std::strerror(errno));
  }
  if (std::fwrite(bytes.data(), 1, bytes.size(), file.get()) != bytes.size() ||
      std::fflush(file.get()) != 0 || std::ferror(file.get()) != 0) {
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
                    int width_px, int height_px, std::span<const PngText> text) {
  check_size("write_png_grey", grey.size(), width_px, height_px, 1);
  write_png_file(path, grey.data(), width_px, height_px, PNG_FORMAT_GRAY, 1, text);
}

std::vector<PngText> read_png_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  static constexpr std::uint8_t kSignature[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() < 8 ||
      !std::equal(std::begin(kSignature), std::end(kSignature), bytes.begin())) {
    throw std::runtime_error("'" + path.string() + "' is not a PNG file (or cannot be read)");
  }
  std::vector<PngText> out;
  for (std::size_t at = 8; at + 12 <= bytes.size();) {
    const std::uint32_t length = read_u32(&bytes[at]);
    if (at + 12 + length > bytes.size()) break;
    if (std::memcmp(&bytes[at + 4], "tEXt", 4) == 0) {
      const auto* data = reinterpret_cast<const char*>(&bytes[at + 8]);
      const std::string field(data, length);
      const auto nul = field.find('\0');
      if (nul != std::string::npos) out.push_back({field.substr(0, nul), field.substr(nul + 1)});
    }
    at += 12 + length;
  }
  return out;
}

}  // namespace ultrasim::render
