// Coulomb's law for one held node: as a slide between steps (slide_held_node), on a linear face
// whose flat part is the plane z = 2 (normal +z, into the tissue) and whose 2 mm rounded rim starts
// 4 mm from its centre; and as the choice between sticking and sliding against friction inside a
// solve (coulomb_hold).

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

TEST(CoulombHold, StickInsideTheFrictionConeSlideAgainstItsBoundOutside) {
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  // Pushed 10 mN, pulled 0.9 mN along: under 0.1 × 10, held in full.
  EXPECT_FALSE(coulomb_hold(n, Eigen::Vector3d(0.9, 0, -10), 0.1).slides);
  // Pulled 3 mN along (0.6, 0.8): slides against 1 mN, opposite the pull.
  const HeldNodeLaw law = coulomb_hold(n, Eigen::Vector3d(1.8, 2.4, -10), 0.1);
  EXPECT_TRUE(law.slides);
  EXPECT_TRUE(law.friction_mn.isApprox(Eigen::Vector3d(-0.6, -0.8, 0)))
      << law.friction_mn.transpose();
  // On a tilted normal the friction lies in its tangent plane.
  const Eigen::Vector3d tilted = Eigen::Vector3d(1, 0, 1).normalized();
  const HeldNodeLaw on_rim = coulomb_hold(tilted, Eigen::Vector3d(0, 5, -10), 0.2);
  EXPECT_TRUE(on_rim.slides);
  EXPECT_NEAR(on_rim.friction_mn.dot(tilted), 0.0, 1e-12);
  EXPECT_NEAR(on_rim.friction_mn.norm(), 0.2 * 10 / std::sqrt(2.0), 1e-12);
}

TEST(CoulombHold, FrictionlessOrPulledOffItSlidesFreelyAndANonFiniteForceSticks) {
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  for (const Eigen::Vector3d& force :
       {Eigen::Vector3d(0, 0, -10), Eigen::Vector3d(3, 0, -10), Eigen::Vector3d(3, 0, 2)}) {
    const HeldNodeLaw frictionless = coulomb_hold(n, force, 0.0);
    EXPECT_TRUE(frictionless.slides) << force.transpose();
    EXPECT_EQ(frictionless.friction_mn, Eigen::Vector3d::Zero());
  }
  // Pulled off the probe (the engine lets go of it next): nothing to hold it along the surface.
  const HeldNodeLaw pulled_off = coulomb_hold(n, Eigen::Vector3d(3, 0, 2), 0.5);
  EXPECT_TRUE(pulled_off.slides);
  EXPECT_EQ(pulled_off.friction_mn, Eigen::Vector3d::Zero());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(coulomb_hold(n, Eigen::Vector3d(nan, 0, -10), 0.0).slides);
}

}  // namespace
}  // namespace ultrasim::sim
