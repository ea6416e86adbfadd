// Volume: index ↔ world mapping and trilinear sampling. Trilinear interpolation reproduces any
// affine function exactly, and world → index is affine, so a linear field is a sharp check even
// with a rotated direction matrix.

#include "ultrasim/imaging/volume.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace ultrasim::imaging {
namespace {

double field(const Eigen::Vector3d& p_mm) {
  return 3.0 + 0.5 * p_mm.x() - 1.25 * p_mm.y() + 2.0 * p_mm.z();
}

Volume<double> linear_volume(const Eigen::Matrix3d& direction) {
  Volume<double> volume({9, 7, 5}, {0.5, 0.75, 1.25}, {-2.0, 4.0, 10.0}, direction);
  for (int k = 0; k < 5; ++k) {
    for (int j = 0; j < 7; ++j) {
      for (int i = 0; i < 9; ++i)
        volume.at(i, j, k) = field(volume.index_to_world(Eigen::Vector3d(i, j, k)));
    }
  }
  return volume;
}

Eigen::Matrix3d tilted() {
  return (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
}

class VolumeSampling : public ::testing::TestWithParam<bool> {};

TEST_P(VolumeSampling, TrilinearIsExactForLinearField) {
  const auto volume = linear_volume(GetParam() ? tilted() : Eigen::Matrix3d::Identity());
  std::mt19937 engine(42);
  const auto unit = [&] { return static_cast<double>(engine()) / 4294967295.0; };
  for (int n = 0; n < 500; ++n) {
    const Eigen::Vector3d index(unit() * 8, unit() * 6, unit() * 4);
    const Eigen::Vector3d world = volume.index_to_world(index);
    EXPECT_NEAR(volume.sample_trilinear(world, -1000.0f), field(world), 1e-4) << index.transpose();
  }
  // Voxel centres, the far corner included (on the hull's edge).
  const Eigen::Vector3d corner = volume.index_to_world(Eigen::Vector3d(8, 6, 4));
  EXPECT_NEAR(volume.sample_trilinear(corner, -1000.0f), field(corner), 1e-4);
  const Eigen::Vector3d origin = volume.origin_mm();
  EXPECT_NEAR(volume.sample_trilinear(origin, -1000.0f), field(origin), 1e-4);
}

TEST_P(VolumeSampling, OutsidePointsReturnTheOutsideValue) {
  const auto volume = linear_volume(GetParam() ? tilted() : Eigen::Matrix3d::Identity());
  for (const Eigen::Vector3d& index :
       {Eigen::Vector3d(-0.01, 3, 2), Eigen::Vector3d(8.01, 3, 2), Eigen::Vector3d(4, -0.5, 2),
        Eigen::Vector3d(4, 6.2, 2), Eigen::Vector3d(4, 3, -3), Eigen::Vector3d(4, 3, 4.001)}) {
    EXPECT_EQ(volume.sample_trilinear(volume.index_to_world(index), -7.0f), -7.0f)
        << index.transpose();
  }
}

TEST_P(VolumeSampling, WorldIndexRoundTrip) {
  const auto volume = linear_volume(GetParam() ? tilted() : Eigen::Matrix3d::Identity());
  const Eigen::Vector3d index(1.25, 5.5, 3.75);
  EXPECT_TRUE(volume.world_to_index(volume.index_to_world(index)).isApprox(index, 1e-12));
  // One step along index i moves spacing_x along the direction's first column.
  const Eigen::Vector3d step = volume.index_to_world({1, 0, 0}) - volume.origin_mm();
  EXPECT_TRUE(step.isApprox(0.5 * volume.direction().col(0), 1e-12));
}

INSTANTIATE_TEST_SUITE_P(Direction, VolumeSampling, ::testing::Values(false, true),
                         [](const auto& param_info) {
                           return param_info.param ? "Tilted" : "Identity";
                         });

TEST(VolumeNearest, PicksTheNearestVoxelOrOutside) {
  Volume<std::uint8_t> labels({3, 3, 3}, {1, 1, 1}, {0, 0, 0});
  labels.at(2, 1, 0) = 5;
  EXPECT_EQ(labels.sample_nearest({1.6, 0.9, 0.4}, 99), 5);
  EXPECT_EQ(labels.sample_nearest({1.4, 0.9, 0.4}, 99), 0);
  EXPECT_EQ(labels.sample_nearest({2.6, 1.0, 0.0}, 99), 99);
}

TEST(VolumeGeometry, ExtentOfAxisAlignedVolume) {
  const Volume<std::uint8_t> volume({241, 161, 181}, {0.25, 0.25, 0.25}, {-30, -20, 0});
  EXPECT_TRUE(volume.world_min_mm().isApprox(Eigen::Vector3d(-30, -20, 0)));
  EXPECT_TRUE(volume.world_max_mm().isApprox(Eigen::Vector3d(30, 20, 45)));
}

}  // namespace
}  // namespace ultrasim::imaging
