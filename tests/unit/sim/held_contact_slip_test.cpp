// Coulomb's law for one held node (slide_held_node), on a linear face whose flat part is the plane
// z = 2 (normal +z, into the tissue) and whose 2 mm rounded rim starts 4 mm from its centre.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ultrasim/sim/contact.hpp"

namespace ultrasim::sim {
namespace {

const ProbeCollider kFace = ProbeCollider::linear_face(
    Eigen::Vector3d(0, 0, 2), Eigen::Quaterniond::Identity(), 12.0, 6.0, 2.0);
const SurfacePoint kOnFlatFace{Eigen::Vector3d(1, 0, 2), Eigen::Vector3d::UnitZ()};
const Eigen::Matrix3d kStiffness = 4.0 * Eigen::Matrix3d::Identity();  // mN/mm

TEST(HeldContactSlip, ANodePulledAlongWithinTheFrictionConeSticks) {
  // Pushed 10 mN into the probe, pulled 0.9 mN along it: under 0.1 × 10.
  const SurfacePoint out =
      slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(0.9, 0, -10), kStiffness, 0.1);
  EXPECT_EQ(out.point_mm, kOnFlatFace.point_mm);
}

TEST(HeldContactSlip, ANodePulledHarderSlidesUntilThePullIsDownToTheBound) {
  // Pulled 3 mN along x and y together (|pull| 3), bound 1 mN: 2 mN over, 4 mN/mm along the pull
  // gives 0.5 mm, along the pull, on the flat face.
  const Eigen::Vector3d pull = 3.0 * Eigen::Vector3d(0.6, 0.8, 0);
  const SurfacePoint out =
      slide_held_node(kFace, kOnFlatFace, pull + Eigen::Vector3d(0, 0, -10), kStiffness, 0.1);
  EXPECT_TRUE(out.point_mm.isApprox(kOnFlatFace.point_mm + 0.5 * Eigen::Vector3d(0.6, 0.8, 0)))
      << out.point_mm.transpose();
  EXPECT_TRUE(out.normal.isApprox(Eigen::Vector3d::UnitZ()));
  // Without friction the whole pull is over: 0.75 mm.
  const SurfacePoint frictionless =
      slide_held_node(kFace, kOnFlatFace, pull + Eigen::Vector3d(0, 0, -10), kStiffness, 0.0);
  EXPECT_NEAR((frictionless.point_mm - kOnFlatFace.point_mm).norm(), 0.75, 1e-12);
}

TEST(HeldContactSlip, TheSlideUsesTheStiffnessAlongThePull) {
  // Stiff across x, soft along y: a pull along y moves the node by the soft stiffness.
  Eigen::Matrix3d k = Eigen::Vector3d(100, 2, 100).asDiagonal();
  const SurfacePoint out = slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(0, 1, -10), k, 0.0);
  EXPECT_TRUE(out.point_mm.isApprox(kOnFlatFace.point_mm + Eigen::Vector3d(0, 0.5, 0)));
}

TEST(HeldContactSlip, OneStepSlidesAtMostItsLimit) {
  const SurfacePoint out =
      slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(-400, 0, -10), kStiffness, 0.1);
  EXPECT_NEAR((out.point_mm - kOnFlatFace.point_mm).norm(), kMaxSlidePerStepMm, 1e-12);
  EXPECT_LT(out.point_mm.x(), kOnFlatFace.point_mm.x());
}

TEST(HeldContactSlip, ANodeSlidingOntoTheRimComesBackOnTheSurface) {
  // 3.5 mm from the centre, pulled outwards 0.9 mm: over the rim's start at 4 mm.
  const SurfacePoint near_rim{Eigen::Vector3d(3.5, 0, 2), Eigen::Vector3d::UnitZ()};
  const SurfacePoint out =
      slide_held_node(kFace, near_rim, Eigen::Vector3d(3.6, 0, -10), kStiffness, 0.0);
  EXPECT_NEAR(kFace.signed_distance_mm(out.point_mm), 0.0, 1e-12);
  EXPECT_GT(out.point_mm.x(), 4.0);
  EXPECT_LT(out.point_mm.z(), 2.0) << "the rim curves back behind the face";
  EXPECT_GT(out.normal.x(), 0.0) << "the rim's normal turns outwards";
  EXPECT_NEAR(out.normal.norm(), 1.0, 1e-12);
}

TEST(HeldContactSlip, ANodePulledOffTheProbeOrWithoutAFiniteForceIsLeftWhereItIs) {
  // Letting go of a node pulled off the probe is the engine's rule, not a slide.
  EXPECT_EQ(slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(5, 0, 1), kStiffness, 0.0).point_mm,
            kOnFlatFace.point_mm);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(
      slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(nan, 0, -10), kStiffness, 0.0).point_mm,
      kOnFlatFace.point_mm);
  EXPECT_EQ(
      slide_held_node(kFace, kOnFlatFace, Eigen::Vector3d(5, 0, -10), Eigen::Matrix3d::Zero(), 0.0)
          .point_mm,
      kOnFlatFace.point_mm);
}

}  // namespace
}  // namespace ultrasim::sim
