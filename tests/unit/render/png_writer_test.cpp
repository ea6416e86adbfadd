#include "ultrasim/render/png_writer.hpp"

#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace ultrasim::render {
namespace {

// Reads a PNG back with libpng itself (not through our code), in the requested format.
std::vector<std::uint8_t> read_png(const std::filesystem::path& path, png_uint_32 format,
                                   int& width, int& height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0) {
    ADD_FAILURE() << image.message;
    return {};
  }
  image.format = format;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr) == 0) {
    ADD_FAILURE() << image.message;
    return {};
  }
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
  return pixels;
}

class PngWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("ultrasim_png_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(PngWriterTest, RgbaRoundTripIsExact) {
  RgbaImage image;
  image.width = 7;  // odd width: rows are not 4-pixel aligned
  image.height = 5;
  for (int i = 0; i < image.width * image.height * 4; ++i) {
    image.rgba.push_back(static_cast<std::uint8_t>(i * 37 % 256));
  }
  const auto path = dir_ / "rgba.png";
  write_png(path, image);
  int width = 0;
  int height = 0;
  const auto pixels = read_png(path, PNG_FORMAT_RGBA, width, height);
  EXPECT_EQ(width, 7);
  EXPECT_EQ(height, 5);
  EXPECT_EQ(pixels, image.rgba);
}

TEST_F(PngWriterTest, GreyRoundTripIsExact) {
  std::vector<std::uint8_t> grey;
  for (int y = 0; y < 9; ++y) {
    for (int x = 0; x < 13; ++x) grey.push_back(static_cast<std::uint8_t>(x * 19 + y * 3));
  }
  const auto path = dir_ / "grey.png";
  write_png_grey(path, grey, 13, 9);
  int width = 0;
  int height = 0;
  const auto pixels = read_png(path, PNG_FORMAT_GRAY, width, height);
  EXPECT_EQ(width, 13);
  EXPECT_EQ(height, 9);
  EXPECT_EQ(pixels, grey);
}

TEST_F(PngWriterTest, UnwritablePathThrowsNamingThePath) {
  RgbaImage image{2, 2, std::vector<std::uint8_t>(16, 128)};
  const auto path = dir_ / "no" / "such" / "folder" / "x.png";
  try {
    write_png(path, image);
    FAIL() << "no exception";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
    EXPECT_NE(message.find("No such file or directory"), std::string::npos) << message;
  }
  const std::vector<std::uint8_t> grey(4, 0);
  EXPECT_THROW(write_png_grey(path, grey, 2, 2), std::runtime_error);
}

TEST_F(PngWriterTest, InconsistentSizesAreRejected) {
  RgbaImage image{3, 3, std::vector<std::uint8_t>(10, 0)};
  EXPECT_THROW(write_png(dir_ / "bad.png", image), std::invalid_argument);
  const std::vector<std::uint8_t> grey(5, 0);
  EXPECT_THROW(write_png_grey(dir_ / "bad.png", grey, 2, 3), std::invalid_argument);
  EXPECT_THROW(write_png_grey(dir_ / "bad.png", grey, 0, 0), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::render

namespace ultrasim::render {
namespace {

// Text fields go in as tEXt chunks the PNG's readers keep (libpng still decodes the pixels) and
// come back in order.
TEST(PngText, FieldsAreWrittenAndReadBack) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("ultrasim-png-text-" + std::to_string(::getpid()) + ".png");
  const std::vector<std::uint8_t> grey = {0, 64, 128, 255, 10, 20};
  const std::vector<PngText> text = {
      {"Case", "default-upper-arm"}, {"Probe position mm", "-2.000 0.000 8.000"}, {"Empty", ""}};
  write_png_grey(path, grey, 3, 2, text);
  const auto back = read_png_text(path);
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back[i].key, text[i].key);
    EXPECT_EQ(back[i].value, text[i].value);
  }
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&image, path.c_str())) << image.message;
  image.format = PNG_FORMAT_GRAY;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  ASSERT_TRUE(png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr));
  EXPECT_EQ(pixels, grey);
  EXPECT_THROW(write_png_grey(path, grey, 3, 2, std::vector<PngText>{{"", "x"}}),
               std::invalid_argument);
  EXPECT_THROW(write_png_grey(path, grey, 3, 2, std::vector<PngText>{{std::string(80, 'k'), ""}}),
               std::invalid_argument);
  std::filesystem::remove(path);
  EXPECT_THROW(read_png_text(path), std::runtime_error);
}

}  // namespace
}  // namespace ultrasim::render
