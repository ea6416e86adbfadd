#include "ultrasim/imaging/display_mapping.hpp"

#include <gtest/gtest.h>

#include <numeric>
#include <vector>

namespace ultrasim::imaging {
namespace {

BscanGrid linear_grid() {
  ProbeGeometry probe;
  probe.depth_mm = 40.0;
  return BscanGrid(probe, 16, 80);
}

std::vector<std::uint8_t> ramp(const BscanGrid& grid) {
  std::vector<std::uint8_t> image(static_cast<std::size_t>(grid.width_px()) * grid.height_px());
  for (std::size_t i = 0; i < image.size(); ++i) image[i] = static_cast<std::uint8_t>(i % 256);
  return image;
}

TEST(DisplayMapping, NeutralControlsLeaveTheImageUntouched) {
  const BscanGrid grid = linear_grid();
  const DisplayMapping mapping(grid, BscanSettings{});
  auto image = ramp(grid);
  const auto before = image;
  mapping.apply(image);
  EXPECT_EQ(image, before);
}

TEST(DisplayMapping, GainAddsDecibelsOnTheLogCompressedScale) {
  BscanSettings settings;
  settings.gain_db = 6.0;  // 6 dB of 60 dB over 255 grey levels: +25.5 grey levels
  const DisplayMapping mapping(linear_grid(), settings);
  EXPECT_EQ(mapping.map(0, 10.0), 0);  // no echo stays black: lumens, background
  EXPECT_EQ(mapping.map(1, 10.0), 27);
  EXPECT_EQ(mapping.map(100, 10.0), 126);
  EXPECT_EQ(mapping.map(240, 10.0), 255);  // saturates
  settings.gain_db = -60.0 + 20.0;
  const DisplayMapping dark(linear_grid(), settings);
  EXPECT_EQ(dark.map(50, 10.0), 0);
}

TEST(DisplayMapping, NarrowerDynamicRangeStretchesTheTopOfTheScale) {
  BscanSettings settings;
  settings.dynamic_range_db = 30.0;  // show only the top 30 dB
  const DisplayMapping mapping(linear_grid(), settings);
  EXPECT_EQ(mapping.map(255, 5.0), 255);
  EXPECT_EQ(mapping.map(128, 5.0), 1);    // 30.1 dB: just above the new floor
  EXPECT_EQ(mapping.map(191, 5.0), 127);  // 44.9 dB: half-way up the 30 dB shown
  EXPECT_EQ(mapping.map(100, 5.0), 0);
}

TEST(DisplayMapping, TgcInterpolatesBetweenSlidersOverDepth) {
  std::array<double, kTgcSliders> tgc{};
  tgc[0] = 0.0;
  tgc[1] = 7.0;
  for (int i = 2; i < kTgcSliders; ++i) tgc[i] = 14.0;
  // Sliders sit at 0, 40/7, 80/7, ... mm for a 40 mm image.
  EXPECT_DOUBLE_EQ(DisplayMapping::tgc_at(tgc, 0.0, 40.0), 0.0);
  EXPECT_NEAR(DisplayMapping::tgc_at(tgc, 20.0 / 7.0, 40.0), 3.5, 1e-12);
  EXPECT_NEAR(DisplayMapping::tgc_at(tgc, 40.0, 40.0), 14.0, 1e-12);
  BscanSettings settings;
  settings.tgc_db = tgc;
  const BscanGrid grid = linear_grid();
  const DisplayMapping mapping(grid, settings);
  std::vector<std::uint8_t> image(16 * 80, 100);
  mapping.apply(image);
  EXPECT_NEAR(image[0], 100, 1);        // top row, 0.25 mm deep: ~0.3 dB of TGC
  EXPECT_GT(image[79 * 16], 100 + 55);  // bottom row: +14 dB = +59.5 grey
  for (int row = 1; row < 80; ++row) EXPECT_GE(image[row * 16], image[(row - 1) * 16]);
}

TEST(DisplayMapping, RowRangesComposeAndConvexOutsidePixelsAreKept) {
  ProbeGeometry probe;
  probe.kind = ProbeKind::kConvex;
  const BscanGrid grid(probe, 64, 64);
  BscanSettings settings;
  settings.gain_db = 10.0;
  const DisplayMapping mapping(grid, settings);
  auto whole = ramp(grid), halves = ramp(grid);
  mapping.apply(whole);
  mapping.apply_rows(halves, 0, 20);
  mapping.apply_rows(halves, 20, 64);
  EXPECT_EQ(whole, halves);
  const auto original = ramp(grid);
  EXPECT_EQ(whole[0], original[0]) << "corner outside the sector keeps the background";
}

}  // namespace
}  // namespace ultrasim::imaging
