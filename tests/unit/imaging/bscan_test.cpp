#include "ultrasim/imaging/bscan.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "affine_volume.hpp"
#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::imaging {
namespace {

using testing::affine_volume;
constexpr double kRounding = testing::kRoundingTolerance;
double expected_echo(const Eigen::Vector3d& p) {
  return testing::affine_echo(p);
}

ProbeGeometry small_linear() {
  ProbeGeometry probe;
  probe.width_mm = 20.0;
  probe.depth_mm = 16.0;
  return probe;
}

TEST(BscanGrid, LinearPixelsSampleTheirCentres) {
  const BscanGrid grid(small_linear(), 40, 32);
  const auto first = grid.pixel_to_plane_mm(0, 0);
  const auto last = grid.pixel_to_plane_mm(39, 31);
  ASSERT_TRUE(first && last);
  EXPECT_NEAR(first->x(), -10.0 + 0.25, 1e-12);
  EXPECT_NEAR(first->y(), 0.25, 1e-12);
  EXPECT_NEAR(last->x(), 10.0 - 0.25, 1e-12);
  EXPECT_NEAR(last->y(), 16.0 - 0.25, 1e-12);
}

TEST(BscanGrid, ConvexSectorMasksPixelsOutsideTheFan) {
  ProbeGeometry probe;
  probe.kind = ProbeKind::kConvex;
  probe.radius_mm = 40.0;
  probe.depth_mm = 60.0;
  probe.fan_angle_deg = 60.0;
  const ImageExtent e = image_extent(probe);
  EXPECT_NEAR(e.x_max_mm, 100.0 * std::sin(M_PI / 6), 1e-9);
  EXPECT_NEAR(e.z_min_mm, -40.0 * (1 - std::cos(M_PI / 6)), 1e-9);
  const BscanGrid grid(probe, 200, 200);
  EXPECT_FALSE(grid.pixel_to_plane_mm(0, 199).has_value());   // outside the sector, bottom left
  EXPECT_FALSE(grid.pixel_to_plane_mm(0, 0).has_value());     // behind the face arc
  EXPECT_TRUE(grid.pixel_to_plane_mm(100, 100).has_value());  // on the centre line
  int inside = 0;
  for (int r = 0; r < 200; ++r)
    for (int c = 0; c < 200; ++c) inside += grid.pixel_to_plane_mm(c, r).has_value();
  // Area of the annular sector over the area of its bounding box.
  const double sector = M_PI / 6 * (100.0 * 100.0 - 40.0 * 40.0);
  EXPECT_NEAR(inside / 40000.0, sector / (e.width_mm() * e.depth_mm()), 0.01);
}

TEST(EchoToGrey, RoundsAndClamps) {
  EXPECT_EQ(echo_to_grey(100.0f), 100);
  EXPECT_EQ(echo_to_grey(100.4f), 100);
  EXPECT_EQ(echo_to_grey(100.6f), 101);
  EXPECT_EQ(echo_to_grey(300.0f), 255);
  EXPECT_EQ(echo_to_grey(-5.0f), 0);
}

TEST(SliceUndeformed, MatchesTheAnalyticVolumeAndShowsBackgroundOutside) {
  const auto volume = affine_volume();
  const BscanGrid grid(small_linear(), 40, 32);
  BscanSettings settings;
  settings.background_grey = 7;
  ProbePose pose;
  pose.face_center_mm = {0.0, 2.0, 0.0};
  std::vector<std::uint8_t> image(40 * 32);
  slice_undeformed(volume, pose, grid, settings, image);
  for (int r = 0; r < 32; ++r)
    for (int c = 0; c < 40; ++c) {
      const auto p = pose.to_patient(*grid.pixel_to_plane_mm(c, r));
      EXPECT_NEAR(image[r * 40 + c], expected_echo(p), kRounding) << c << "," << r;
    }
  pose.face_center_mm = {0.0, 50.0, 0.0};  // beside the volume
  slice_undeformed(volume, pose, grid, settings, image);
  for (auto px : image) EXPECT_EQ(px, 7);
}

struct MeshFixture {
  geometry::TetMesh mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-20, -10, 0}, {20, 10, 30}, {9, 5, 7}));
};

TEST(SliceDeformedReference, EqualsUndeformedSlicingOnTheRestMesh) {
  MeshFixture f;
  const auto volume = affine_volume();
  const geometry::TetLocator locator(f.mesh);
  const BscanGrid grid(small_linear(), 64, 48);
  ProbePose pose;
  pose.face_center_mm = {1.3, -2.1, 0.0};
  pose.axes = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<std::uint8_t> a(64 * 48), b(64 * 48);
  slice_undeformed(volume, pose, grid, BscanSettings{}, a);
  slice_deformed_reference(volume, f.mesh, locator, pose, grid, BscanSettings{}, b);
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_LE(std::abs(a[i] - b[i]), 1) << i;
}

TEST(SliceDeformedReference, MapsAnAffineDeformationBackExactly) {
  MeshFixture f;
  const auto volume = affine_volume();
  // Tissue squashed by 20 % in depth towards the deep face and sheared sideways.
  Eigen::Matrix3d a;
  a << 1.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0, 0.8;
  const Eigen::Vector3d b(0.0, 0.0, 6.0);
  std::vector<Eigen::Vector3d> deformed;
  for (const auto& x : f.mesh.rest_positions_mm) deformed.push_back(a * x + b);
  geometry::TetLocator locator(f.mesh);
  locator.rebuild(deformed);
  const BscanGrid grid(small_linear(), 40, 32);
  BscanSettings settings;
  settings.background_grey = 3;
  ProbePose pose;
  pose.face_center_mm = {0.0, 1.0, 2.0};
  std::vector<std::uint8_t> image(40 * 32);
  slice_deformed_reference(volume, f.mesh, locator, pose, grid, settings, image);
  int inside = 0, outside = 0;
  for (int r = 0; r < 32; ++r)
    for (int c = 0; c < 40; ++c) {
      const Eigen::Vector3d p = pose.to_patient(*grid.pixel_to_plane_mm(c, r));
      const Eigen::Vector3d rest = a.inverse() * (p - b);
      const bool in_mesh = rest.z() >= 0.0 && rest.z() <= 30.0 && std::abs(rest.x()) <= 20.0;
      if (in_mesh) {
        EXPECT_NEAR(image[r * 40 + c], expected_echo(rest), kRounding) << c << "," << r;
        ++inside;
      } else {
        EXPECT_EQ(image[r * 40 + c], 3) << "pixel above the compressed skin must be background";
        ++outside;
      }
    }
  EXPECT_GT(inside, 0);
  EXPECT_GT(outside, 0);
}

}  // namespace
}  // namespace ultrasim::imaging
