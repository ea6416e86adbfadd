// The printable dodecahedron net: twelve regular pentagons of the given edge, eleven folds
// along shared edges, and no two faces overlapping on the page.

#include "ultrasim/tracking/dodecahedron_net.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace ultrasim::tracking {
namespace {

// Separating-axis test for two convex polygons: true when their interiors overlap by more than
// `tolerance_mm` along every edge normal of both.
bool interiors_overlap(const NetFace& a, const NetFace& b, double tolerance_mm) {
  for (const NetFace* face : {&a, &b}) {
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector2d e = face->corners_mm[(k + 1) % 5] - face->corners_mm[k];
      const Eigen::Vector2d n(-e.y(), e.x());
      double a_lo = std::numeric_limits<double>::max(), a_hi = -a_lo, b_lo = a_lo, b_hi = -a_lo;
      for (const auto& c : a.corners_mm) {
        a_lo = std::min(a_lo, c.dot(n));
        a_hi = std::max(a_hi, c.dot(n));
      }
      for (const auto& c : b.corners_mm) {
        b_lo = std::min(b_lo, c.dot(n));
        b_hi = std::max(b_hi, c.dot(n));
      }
      if (a_hi <= b_lo + tolerance_mm * n.norm() || b_hi <= a_lo + tolerance_mm * n.norm()) {
        return false;
      }
    }
  }
  return true;
}

int shared_corners(const NetFace& a, const NetFace& b) {
  int shared = 0;
  for (const auto& p : a.corners_mm) {
    for (const auto& q : b.corners_mm) shared += (p - q).norm() < 1e-9;
  }
  return shared;
}

TEST(DodecahedronNet, TwelveRegularPentagonsElevenFoldsNoOverlap) {
  const double edge = 40.0;
  const DodecahedronNet net = make_dodecahedron_net(edge, 5.0);
  ASSERT_EQ(net.faces.size(), 12u);
  for (const NetFace& f : net.faces) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (int k = 0; k < 5; ++k) {
      EXPECT_NEAR((f.corners_mm[(k + 1) % 5] - f.corners_mm[k]).norm(), edge, 1e-9);
      mean += f.corners_mm[k] / 5;
      EXPECT_NEAR((f.corners_mm[k] - f.centre_mm).norm(), edge / (2 * std::sin(M_PI / 5)), 1e-9);
      EXPECT_GE(f.corners_mm[k].x(), 5.0 - 1e-9);
      EXPECT_GE(f.corners_mm[k].y(), 5.0 - 1e-9);
      EXPECT_LE(f.corners_mm[k].x(), net.size_mm.x() - 5.0 + 1e-9);
      EXPECT_LE(f.corners_mm[k].y(), net.size_mm.y() - 5.0 + 1e-9);
    }
    EXPECT_LT((mean - f.centre_mm).norm(), 1e-9);
    EXPECT_NEAR(f.up.norm(), 1.0, 1e-12);
  }
  ASSERT_EQ(net.folds.size(), 11u);
  for (const auto& [a, b] : net.folds) {
    EXPECT_EQ(shared_corners(net.faces[a], net.faces[b]), 2) << a << "-" << b;
  }
  // Connected through the folds: a tree over the twelve faces.
  std::vector<int> group(12);
  for (int i = 0; i < 12; ++i) group[i] = i;
  for (const auto& [a, b] : net.folds) {
    const int from = group[b], to = group[a];
    for (int& g : group) g = g == from ? to : g;
  }
  for (int g : group) EXPECT_EQ(g, group[0]);
  for (int a = 0; a < 12; ++a) {
    for (int b = a + 1; b < 12; ++b) {
      EXPECT_FALSE(interiors_overlap(net.faces[a], net.faces[b], 1e-6)) << a << " and " << b;
    }
  }
  EXPECT_TRUE(interiors_overlap(net.faces[0], net.faces[0], 1e-6)) << "the check can fail";
  EXPECT_NEAR(pentagon_inradius_mm(edge), edge / (2 * std::tan(M_PI / 5)), 1e-12);
  EXPECT_THROW(make_dodecahedron_net(0.0), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::tracking
