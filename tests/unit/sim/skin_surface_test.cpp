// The skin's own mass-spring surface: it dents under the probe where it is free, springs back
// when the probe lifts, follows the tissue where it lies over it without a seam, and never
// allocates or shows garbage.

#include "ultrasim/sim/skin_surface.hpp"

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

namespace ultrasim::sim {
namespace {

constexpr double kDt = 1.0 / 60.0;

// The tissue under x, y in [0, 20] mm; the skin at z = 0 reaches beyond it.
SkinSurface skin() {
  return SkinSurface({0.0, 0.0}, {20.0, 20.0}, 0.0);
}

std::vector<Eigen::Vector3d> at_rest(const SkinSurface& s, double lift_mm = 0.0) {
  std::vector<Eigen::Vector3d> out;
  for (auto n : s.driven_nodes())
    out.push_back(s.rest_positions_mm()[static_cast<std::size_t>(n)] +
                  Eigen::Vector3d(0, 0, lift_mm));
  return out;
}

// A linear probe pressed `depth_mm` into the skin at (x, y), off the tissue.
ProbeCollider probe_at(double x, double y, double depth_mm) {
  return ProbeCollider::linear_face({x, y, depth_mm}, Eigen::Quaterniond::Identity(), 38.0, 10.0,
                                    2.0);
}

TEST(SkinSurface, DentsUnderTheProbeAndSpringsBack) {
  SkinSurface s = skin();
  const auto driven = at_rest(s);
  // Off the tissue (x = -15): the free skin is pushed down to the probe's face.
  const ProbeCollider probe = probe_at(-12.0, 10.0, 4.0);
  for (int f = 0; f < 30; ++f) ASSERT_TRUE(s.step(&probe, driven, kDt));
  EXPECT_NEAR(s.max_dent_mm(), 4.0, 0.05);
  // Lifted well clear: back to its rest shape within half a second.
  for (int f = 0; f < 30; ++f) ASSERT_TRUE(s.step(nullptr, driven, kDt));
  EXPECT_LT(s.max_dent_mm(), 0.05);
  for (std::size_t n = 0; n < s.rest_positions_mm().size(); ++n) {
    EXPECT_LT((s.positions_mm()[n] - s.rest_positions_mm()[n]).norm(), 0.1) << n;
  }
}

// A view the scheduler skipped for a few frames moves the skin by their time at once: six
// frames' step springs back as far as six frames do (more substeps, not a longer one: stable).
TEST(SkinSurface, ALongerStepSpringsBackAsFarAsTheFramesItStandsFor) {
  SkinSurface every_frame = skin(), skipped = skin();
  const auto driven = at_rest(every_frame);
  const ProbeCollider probe = probe_at(-12.0, 10.0, 4.0);
  for (int f = 0; f < 30; ++f) {
    ASSERT_TRUE(every_frame.step(&probe, driven, kDt));
    ASSERT_TRUE(skipped.step(&probe, driven, kDt));
  }
  for (int f = 0; f < 12; ++f) ASSERT_TRUE(every_frame.step(nullptr, driven, kDt));
  for (int f = 0; f < 2; ++f) ASSERT_TRUE(skipped.step(nullptr, driven, 6 * kDt));
  EXPECT_LT(skipped.max_dent_mm(), 0.05);
  EXPECT_NEAR(skipped.max_dent_mm(), every_frame.max_dent_mm(), 0.02);
  for (std::size_t n = 0; n < skipped.rest_positions_mm().size(); ++n) {
    EXPECT_LT((skipped.positions_mm()[n] - every_frame.positions_mm()[n]).norm(), 0.05) << n;
  }
}

// Over the tissue the skin is the tissue's surface; next to it the free skin follows, so the
// step across the tissue's edge is a slope, not a seam.
TEST(SkinSurface, FollowsTheTissueWithoutASeam) {
  SkinSurface s = skin();
  const auto pressed = at_rest(s, 3.0);  // the tissue's surface 3 mm down
  for (int f = 0; f < 60; ++f) ASSERT_TRUE(s.step(nullptr, pressed, kDt));
  for (std::size_t k = 0; k < pressed.size(); ++k) {
    EXPECT_EQ(s.positions_mm()[static_cast<std::size_t>(s.driven_nodes()[k])], pressed[k]);
  }
  // The free node next to the tissue's edge (x < 0, one grid step out), halfway along it, is
  // pulled well down with it.
  double next_to_edge = 0.0, best = 1e9;
  for (std::size_t n = 0; n < s.rest_positions_mm().size(); ++n) {
    const auto& r = s.rest_positions_mm()[n];
    const double off = std::abs(r.x() + SkinSettings{}.spacing_mm) + std::abs(r.y() - 10.0);
    if (r.x() < 0.0 && off < best) {
      best = off;
      next_to_edge = s.positions_mm()[n].z();
    }
  }
  EXPECT_GT(next_to_edge, 0.5);  // measured 0.81 mm, 4 mm from a node 3 mm down
  EXPECT_LT(next_to_edge, 3.0);
}

TEST(SkinSurface, StepsWithoutAllocatingAndRefusesGarbage) {
  SkinSurface s = skin();
  auto driven = at_rest(s);
  const ProbeCollider probe = probe_at(-12.0, 10.0, 2.0);
  s.step(&probe, driven, kDt);
  testing::start_counting_allocations();
  for (int f = 0; f < 5; ++f) s.step(&probe, driven, kDt);
  EXPECT_EQ(testing::stop_counting_allocations(), 0);
  const std::vector<Eigen::Vector3d> before(s.positions_mm().begin(), s.positions_mm().end());
  driven[0].x() = std::nan("");
  EXPECT_FALSE(s.step(&probe, driven, kDt));
  EXPECT_TRUE(std::equal(before.begin(), before.end(), s.positions_mm().begin()));
  EXPECT_FALSE(s.step(&probe, std::span(driven).first(3), kDt));
  EXPECT_THROW(SkinSurface({0, 0}, {0, 10}, 0.0), std::invalid_argument);
}

TEST(SkinSurface, TrianglesFaceOutOfTheBody) {
  const SkinSurface s = skin();
  const auto& p = s.rest_positions_mm();
  const auto t = s.triangles();
  ASSERT_EQ(t.size() % 3, 0u);
  for (std::size_t i = 0; i < t.size(); i += 3) {
    const Eigen::Vector3d n = (p[t[i + 1]] - p[t[i]]).cross(p[t[i + 2]] - p[t[i]]);
    ASSERT_LT(n.z(), 0.0) << "triangle " << i / 3;  // outside is −z, above the skin
  }
}

}  // namespace
}  // namespace ultrasim::sim
