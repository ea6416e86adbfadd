#include "ultrasim/sim/probe_collider.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "naive_contacts.hpp"
#include "ultrasim/sim/contact.hpp"

namespace ultrasim::sim {
namespace {

const Eigen::Quaterniond kTilted(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));

// Inside tests written from the shapes' definitions, independent of the distance code.
bool inside_rounded_box(const Eigen::Vector3d& local, const Eigen::Vector3d& half, double r) {
  const Eigen::Vector3d inner = half - Eigen::Vector3d::Constant(r);
  return (local - local.cwiseMax(-inner).cwiseMin(inner)).norm() < r;
}

TEST(ProbeCollider, SphereDistanceAndPushOutAreRadial) {
  const auto s = ProbeCollider::sphere({Eigen::Vector3d(1, 2, -27), 30.0});
  EXPECT_NEAR(s.signed_distance_mm(Eigen::Vector3d(1, 2, 3)), 0.0, 1e-12);
  EXPECT_NEAR(s.signed_distance_mm(Eigen::Vector3d(1, 2, 1)), -2.0, 1e-12);
  const auto p = s.closest_surface_point(Eigen::Vector3d(1, 2, 1));
  EXPECT_TRUE(p.point_mm.isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_TRUE(p.normal.isApprox(Eigen::Vector3d::UnitZ()));
}

TEST(ProbeCollider, LinearFaceIsFlatAtTheFaceCentreAndFacesAlongTheBeam) {
  const Eigen::Vector3d face(4, -3, 2);
  const auto probe = ProbeCollider::linear_face(face, kTilted, 38.0, 10.0, 2.0);
  const Eigen::Matrix3d frame = kTilted.toRotationMatrix();
  const Eigen::Vector3d beam = frame.col(2);
  EXPECT_NEAR(probe.signed_distance_mm(face), 0.0, 1e-12);
  EXPECT_NEAR(probe.signed_distance_mm(face + 1.5 * beam), 1.5, 1e-12);
  EXPECT_NEAR(probe.signed_distance_mm(face - 1.5 * beam), -1.5, 1e-12);
  // Anywhere on the flat part of the face (|lateral| < 17, |elevation| < 3).
  const Eigen::Vector3d on_face = face + 15.0 * frame.col(0) - 2.5 * frame.col(1) - 0.5 * beam;
  const auto s = probe.closest_surface_point(on_face);
  EXPECT_TRUE(s.normal.isApprox(beam));
  EXPECT_TRUE(s.point_mm.isApprox(on_face + 0.5 * beam));
}

TEST(ProbeCollider, RoundedBoxDistanceAgreesWithItsDefinitionEverywhere) {
  const Eigen::Vector3d face(0, 0, 5);
  const auto probe = ProbeCollider::linear_face(face, kTilted, 38.0, 10.0, 2.0, 60.0);
  const Eigen::Matrix3d frame = kTilted.toRotationMatrix();
  const Eigen::Vector3d centre = face - 30.0 * frame.col(2);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-40, 40);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d p = centre + Eigen::Vector3d(u(rng), u(rng) / 3, u(rng));
    const double d = probe.signed_distance_mm(p);
    const auto s = probe.closest_surface_point(p);
    const bool inside =
        inside_rounded_box(frame.transpose() * (p - centre), Eigen::Vector3d(19, 5, 30), 2.0);
    EXPECT_EQ(d < 0.0, inside) << "point " << p.transpose();
    EXPECT_NEAR(std::abs(d), (p - s.point_mm).norm(), 1e-9);
    EXPECT_NEAR(s.normal.norm(), 1.0, 1e-12);
    // The closest point is on the surface: its own distance is zero.
    EXPECT_NEAR(probe.signed_distance_mm(s.point_mm), 0.0, 1e-9);
  }
}

TEST(ProbeCollider, ConvexFaceIsAnArcAboutAnElevationAxis) {
  const Eigen::Vector3d face(0, 0, 3);
  const auto probe =
      ProbeCollider::convex_face(face, Eigen::Quaterniond::Identity(), 50.0, 12.0, 1.0);
  const Eigen::Vector3d axis_point = face - Eigen::Vector3d(0, 0, 50);
  for (double angle : {-0.4, -0.1, 0.0, 0.2, 0.5}) {
    const Eigen::Vector3d radial(std::sin(angle), 0.0, std::cos(angle));
    const Eigen::Vector3d on_arc = axis_point + 50.0 * radial;
    EXPECT_NEAR(probe.signed_distance_mm(on_arc), 0.0, 1e-9) << angle;
    EXPECT_NEAR(probe.signed_distance_mm(on_arc + 2.0 * radial), 2.0, 1e-9) << angle;
    EXPECT_NEAR(probe.signed_distance_mm(on_arc - 2.0 * radial), -2.0, 1e-9) << angle;
    EXPECT_TRUE(probe.closest_surface_point(on_arc + radial).normal.isApprox(radial));
  }
  // Beyond the face's thickness in elevation the probe is not there.
  EXPECT_GT(probe.signed_distance_mm(face + Eigen::Vector3d(0, 7.5, -1)), 0.0);
}

TEST(ProbeCollider, RejectsImpossibleShapes) {
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  EXPECT_THROW(ProbeCollider::linear_face(c, q, 0.0, 10.0, 1.0), std::invalid_argument);
  EXPECT_THROW(ProbeCollider::linear_face(c, q, 38.0, 10.0, 5.0), std::invalid_argument);
  EXPECT_THROW(ProbeCollider::convex_face(c, q, 50.0, 12.0, 6.0), std::invalid_argument);
  EXPECT_THROW(ProbeCollider::sphere({c, -1.0}), std::invalid_argument);
}

TEST(FindContacts, ListsFreeNodesInsideWithTheirPushOutTargets) {
  const auto probe = ProbeCollider::linear_face(Eigen::Vector3d(0, 0, 1.0),
                                                Eigen::Quaterniond::Identity(), 20.0, 10.0, 1.0);
  const std::vector<Eigen::Vector3d> nodes = {
      {0, 0, 0}, {0, 0, 2}, {3, 2, 0.5}, {30, 0, 0}, {0, 0, -0.5}};
  const std::vector<std::uint8_t> fixed = {0, 0, 0, 0, 1};
  std::vector<NodeContact> contacts;
  find_contacts(probe, nodes, fixed, 1e-9, contacts);
  ASSERT_EQ(contacts.size(), 2u);
  EXPECT_EQ(contacts[0].node, 0);
  EXPECT_TRUE(contacts[0].target_mm.isApprox(Eigen::Vector3d(0, 0, 1)));
  EXPECT_NEAR(contacts[0].depth_mm, 1.0, 1e-12);
  EXPECT_EQ(contacts[1].node, 2);
  EXPECT_NEAR(contacts[1].depth_mm, 0.5, 1e-12);
}

// The three shapes at random poses: the linear face with its 80 mm body, the convex face with
// its rims, the sphere.
std::vector<ProbeCollider> probes_at_random_poses(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<ProbeCollider> out;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d c(10.0 * unit(rng), 10.0 * unit(rng), 5.0 * unit(rng));
    const Eigen::Quaterniond q =
        i == 0 ? Eigen::Quaterniond::Identity()
               : Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)))
                     .normalized();
    out.push_back(ProbeCollider::linear_face(c, q, 38.0, 10.0, 1.0));
    out.push_back(ProbeCollider::convex_face(c, q, 50.0, 12.0, 2.0));
    out.push_back(ProbeCollider::sphere({c, 20.0}));
  }
  return out;
}

// Every point of the solid lies in its box (points scattered around the probe: those inside it,
// and the closest surface points of those outside), and the box is no larger than the solid: its
// faces are the solid's farthest points along the axes.
TEST(ProbeCollider, ItsBoxHoldsTheSolidAndNoMore) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const ProbeCollider& probe : probes_at_random_poses(rng, 6)) {
    const Eigen::AlignedBox3d box = probe.bounds_mm();
    Eigen::AlignedBox3d reached;  // empty
    for (int i = 0; i < 20'000; ++i) {
      const Eigen::Vector3d p = box.center() + 0.75 * box.sizes().cwiseProduct(Eigen::Vector3d(
                                                          unit(rng), unit(rng), unit(rng)));
      if (probe.signed_distance_mm(p) <= 0.0) {
        EXPECT_TRUE(box.contains(p)) << p.transpose();
        continue;
      }
      // From outside, the closest point is on the surface (from inside, the push-out place).
      const Eigen::Vector3d on_surface = probe.closest_surface_point(p).point_mm;
      ASSERT_LE(std::abs(probe.signed_distance_mm(on_surface)), 1e-9);
      EXPECT_TRUE(box.exteriorDistance(on_surface) < 1e-9) << on_surface.transpose();
      reached.extend(on_surface);
    }
    EXPECT_TRUE(box.contains(reached));
    // The solid's farthest point along each axis (the closest point to one a kilometre out:
    // within 10⁻³ mm of the support point for a solid this size) lies on the box's face.
    for (int axis = 0; axis < 3; ++axis) {
      for (const double side : {-1.0, 1.0}) {
        const Eigen::Vector3d far = box.center() + side * 1e6 * Eigen::Vector3d::Unit(axis);
        const double reach = probe.closest_surface_point(far).point_mm[axis];
        const double face = side > 0.0 ? box.max()[axis] : box.min()[axis];
        EXPECT_NEAR(reach, face, 0.01) << "axis " << axis << ", side " << side;
      }
    }
  }
}

// Nodes outside the probe's box are left out before the closest-point query: the same contacts,
// in the same order, with the same targets, normals and depths as asking every node (the
// reference), for nodes scattered inside, around and far from each shape at random poses, some
// fixed, at the engines' tolerances.
TEST(FindContacts, LeavesOutOnlyNodesAskingEveryNodeWouldLeaveOut) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Eigen::Vector3d> nodes(5'000);
  std::vector<std::uint8_t> fixed(nodes.size());
  std::vector<NodeContact> fast, reference;
  int compared = 0;
  for (const ProbeCollider& probe : probes_at_random_poses(rng, 8)) {
    const Eigen::AlignedBox3d box = probe.bounds_mm();
    for (std::size_t n = 0; n < nodes.size(); ++n) {
      nodes[n] = box.center() +
                 0.7 * box.sizes().cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
      fixed[n] = n % 17 == 0;
    }
    for (const double tolerance : {1e-9, 1e-6, 0.5}) {
      find_contacts(probe, nodes, fixed, tolerance, fast);
      testing::naive_find_contacts(probe, nodes, fixed, tolerance, reference);
      ASSERT_EQ(fast.size(), reference.size());
      EXPECT_GT(reference.size(), 0u);
      for (std::size_t i = 0; i < fast.size(); ++i) {
        EXPECT_EQ(fast[i].node, reference[i].node);
        EXPECT_EQ(fast[i].target_mm, reference[i].target_mm);
        EXPECT_EQ(fast[i].normal, reference[i].normal);
        EXPECT_EQ(fast[i].depth_mm, reference[i].depth_mm);
      }
      ++compared;
    }
  }
  EXPECT_EQ(compared, 72);
}

}  // namespace
}  // namespace ultrasim::sim
