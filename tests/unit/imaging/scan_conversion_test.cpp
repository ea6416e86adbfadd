#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "ultrasim/imaging/bscan.hpp"

namespace ultrasim::imaging {
namespace {

ProbeGeometry convex_probe() {
  ProbeGeometry p;
  p.kind = ProbeKind::kConvex;
  p.radius_mm = 40.0;
  p.depth_mm = 60.0;
  p.fan_angle_deg = 60.0;
  return p;
}

TEST(ScanLineGrid, LinearLinesAreParallelAndEvenlySpaced) {
  ProbeGeometry p;
  p.width_mm = 40.0;
  p.depth_mm = 50.0;
  const BscanGrid grid = BscanGrid::scan_lines(p, 80, 100);
  EXPECT_EQ(grid.layout(), BscanGrid::Layout::kScanLines);
  const auto first = *grid.pixel_to_plane_mm(0, 0);
  EXPECT_NEAR(first.x(), -20.0 + 0.25, 1e-12);
  EXPECT_NEAR(first.y(), 0.25, 1e-12);
  EXPECT_NEAR(grid.pixel_to_plane_mm(79, 99)->x(), 20.0 - 0.25, 1e-12);
  EXPECT_NEAR(*grid.pixel_depth_mm(3, 99), 49.75, 1e-12);
}

TEST(ScanLineGrid, ConvexLinesFanOutFromTheCentreOfCurvature) {
  const ProbeGeometry p = convex_probe();
  const BscanGrid grid = BscanGrid::scan_lines(p, 65, 120);
  // The middle line points straight down; samples sit at even radii along it.
  const auto mid = *grid.pixel_to_plane_mm(32, 10);
  EXPECT_NEAR(mid.x(), 0.0, 1e-12);
  EXPECT_NEAR(mid.y(), 10.5 * 60.0 / 120.0, 1e-12);
  // Every sample of the outermost line lies on a ray at (fan/2 − half a line) from the axis.
  const double expected = (30.0 - 30.0 / 65.0) * M_PI / 180.0;
  for (int s : {0, 60, 119}) {
    const auto q = *grid.pixel_to_plane_mm(64, s);
    EXPECT_NEAR(std::atan2(q.x(), q.y() + 40.0), expected, 1e-12);
    EXPECT_NEAR(*grid.pixel_depth_mm(64, s), (s + 0.5) * 0.5, 1e-9);
  }
}

TEST(ScanConverter, ReproducesAnAffineLineImageOnTheLinearDisplay) {
  ProbeGeometry p;
  p.width_mm = 32.0;
  p.depth_mm = 40.0;
  const BscanGrid lines = BscanGrid::scan_lines(p, 64, 100);
  const BscanGrid display(p, 128, 160);
  std::vector<std::uint8_t> line_image(64 * 100);
  for (int s = 0; s < 100; ++s)
    for (int l = 0; l < 64; ++l) line_image[s * 64 + l] = static_cast<std::uint8_t>(2 * l + s);
  std::vector<std::uint8_t> out(128 * 160);
  const ScanConverter converter(lines, display, 7);
  converter.apply(line_image, out);
  for (int row = 0; row < 160; ++row)
    for (int col = 0; col < 128; ++col) {
      const double line = (col + 0.5) / 128 * 64 - 0.5, sample = (row + 0.5) / 160 * 100 - 0.5;
      const double expected = 2 * std::clamp(line, 0.0, 63.0) + std::clamp(sample, 0.0, 99.0);
      EXPECT_NEAR(out[row * 128 + col], expected, 0.51) << col << "," << row;
    }
}

// A convex scan: slicing along the scan lines and converting must show what slicing the display
// grid directly shows, up to the interpolation between lines.
TEST(ScanConverter, ConvexScanMatchesDirectSlicingOfASmoothVolume) {
  const ProbeGeometry p = convex_probe();
  Volume<std::uint8_t> volume({121, 3, 121}, {1.0, 1.0, 1.0}, {-60.0, -1.0, -20.0});
  for (int k = 0; k < 121; ++k)
    for (int i = 0; i < 121; ++i) {
      const auto w = volume.index_to_world({double(i), 0.0, double(k)});
      for (int j = 0; j < 3; ++j)
        volume.at(i, j, k) =
            static_cast<std::uint8_t>(std::clamp(120.0 + 1.0 * w.x() + 1.5 * w.z(), 0.0, 255.0));
    }
  const BscanGrid lines = BscanGrid::scan_lines(p, 192, 256);
  const BscanGrid display(p, 200, 160);
  BscanSettings settings;
  settings.background_grey = 0;
  ProbePose pose;
  std::vector<std::uint8_t> line_image(192 * 256), converted(200 * 160), direct(200 * 160);
  slice_undeformed(volume, pose, lines, settings, line_image);
  ScanConverter(lines, display, 0).apply(line_image, converted);
  slice_undeformed(volume, pose, display, settings, direct);
  int compared = 0;
  for (int i = 0; i < 200 * 160; ++i) {
    if (direct[i] == 0 || converted[i] == 0) continue;  // sector edges
    EXPECT_NEAR(converted[i], direct[i], 2) << i;
    ++compared;
  }
  EXPECT_GT(compared, 200 * 160 / 3);
}

TEST(ScanConverter, RowRangesComposeAndGridLayoutsAreChecked) {
  const ProbeGeometry p = convex_probe();
  const BscanGrid lines = BscanGrid::scan_lines(p, 32, 40);
  const BscanGrid display(p, 50, 40);
  std::vector<std::uint8_t> line_image(32 * 40);
  for (std::size_t i = 0; i < line_image.size(); ++i)
    line_image[i] = static_cast<std::uint8_t>(i * 7);
  std::vector<std::uint8_t> whole(50 * 40), halves(50 * 40);
  const ScanConverter converter(lines, display, 3);
  converter.apply(line_image, whole);
  converter.apply_rows(line_image, halves, 0, 13);
  converter.apply_rows(line_image, halves, 13, 40);
  EXPECT_EQ(whole, halves);
  EXPECT_EQ(whole[0], 3) << "outside the sector";
  EXPECT_THROW(ScanConverter(display, display, 0), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::imaging
