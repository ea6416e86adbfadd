// A probe face slid along a homogeneous slab at a constant depth, far from the slab's edges: by
// translation invariance the tissue's answer, and so the force on the probe, is the same wherever
// the face stops, if the contact lets the skin slide under it (frictionless, as on gel). The exact
// FEM's frictionless contact is held to that law, and so is the Coulomb slip of the PCG FEM's and
// the MSDS's held nodes without friction (the PCG FEM's figures to the exact FEM's). With the gel's
// friction the face shears the skin a little and its force stays bounded. The published stick
// contact (HeldContactModel::kStick) instead holds every node it catches in all three directions,
// so the face drags the skin along and ploughs the tissue ahead: pinned with its figures.

#include <gtest/gtest.h>

#include <cstdio>

#include "engine_settings.hpp"
#include "slab_region.hpp"
#include "ultrasim/sim/engine_factory.hpp"

namespace ultrasim::sim {
namespace {

using testing::max_norm;
using ultrasim::testing::with_held_contact;

constexpr double kDepthMm = 2.0;
constexpr double kStartXmm = 20.0;
constexpr double kSlideMm = 30.0;
constexpr int kPressFrames = 20;
constexpr int kSlideFrames = 120;
constexpr int kSettleFrames = 40;

// 70 × 26 × 14 mm at 2 mm (22 mm deep with 12 node layers), fixed at its floor.
testing::SlabRegion homogeneous_slab(int node_layers = 8) {
  return testing::make_slab_region({36, 14, node_layers}, [](const Eigen::Vector3d&) {
    return Material{1, "muscle", 30.0, 0.45};
  });
}

ProbeCollider face_at(double x_mm, double depth_mm) {
  // 12 mm across the slide, 6 mm along it, 2 mm edges, beam straight down.
  return ProbeCollider::linear_face(
      Eigen::Vector3d(x_mm, 13.0, depth_mm),
      Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * 3.141592653589793, Eigen::Vector3d::UnitZ())),
      12.0, 6.0, 2.0);
}

struct SlideFigures {
  double force_before_n = 0.0;  // pressed and settled at the start
  double force_after_n = 0.0;   // slid and settled at the end
  double largest_move_before_mm = 0.0;
  double largest_move_after_mm = 0.0;
  int refused_frames = 0;  // while sliding and settling
};

SlideFigures slide(EngineKind kind, const testing::SlabRegion& r,
                   const EngineSettings& settings = {}, double depth_mm = kDepthMm,
                   int settle_frames = kSettleFrames) {
  std::vector<std::uint8_t> skin(r.mesh.node_count(), 0);
  for (int n = 0; n < r.mesh.node_count(); ++n) skin[n] = r.mesh.rest_positions_mm[n].z() == 0.0;
  auto engine = make_engine(kind, r.mesh, r.materials, r.fixed, settings, skin);
  SlideFigures out;
  EngineStepStats s;
  for (int f = 0; f < kPressFrames + settle_frames; ++f) {
    const double depth = depth_mm * std::min(1.0, (f + 1.0) / kPressFrames);
    const ProbeCollider face = face_at(kStartXmm, depth);
    s = engine->step(&face, 1.0 / 60);
  }
  out.force_before_n = s.contact_force_n;
  out.largest_move_before_mm = max_norm(engine->displacements_mm());
  for (int f = 0; f < kSlideFrames + settle_frames; ++f) {
    const double x = kStartXmm + kSlideMm * std::min(1.0, (f + 1.0) / kSlideFrames);
    const ProbeCollider face = face_at(x, depth_mm);
    s = engine->step(&face, 1.0 / 60);
    out.refused_frames += s.diverged;
  }
  out.force_after_n = s.contact_force_n;
  out.largest_move_after_mm = max_norm(engine->displacements_mm());
  const HeldContactSettings& held = kind == EngineKind::kPcgFem ? settings.fem.contact
                                    : kind == EngineKind::kCorotationalFem
                                        ? settings.corotational.contact
                                        : settings.msds.contact;
  std::printf("%-14s %-13s force %.2f -> %.2f N, largest move %.2f -> %.2f mm%s\n",
              std::string(engine_key(kind)).c_str(),
              kind == EngineKind::kExactFem            ? "frictionless"
              : held.model == HeldContactModel::kStick ? "stick"
              : held.friction_coefficient == 0.0
                  ? "slip, mu 0"
                  : ("slip, mu " + std::to_string(held.friction_coefficient).substr(0, 4)).c_str(),
              out.force_before_n, out.force_after_n, out.largest_move_before_mm,
              out.largest_move_after_mm, s.diverged ? " (the last frame refused)" : "");
  return out;
}

TEST(SlidingProbe, TheFrictionlessExactFemPressesAsHardWhereverTheFaceStops) {
  const testing::SlabRegion r = homogeneous_slab();
  const SlideFigures exact = slide(EngineKind::kExactFem, r);
  ASSERT_GT(exact.force_before_n, 0.1);
  EXPECT_NEAR(exact.force_after_n, exact.force_before_n, 0.03 * exact.force_before_n);
  EXPECT_NEAR(exact.largest_move_after_mm, exact.largest_move_before_mm,
              0.03 * exact.largest_move_before_mm)
      << "the skin slid under the face, not along with it";
}

constexpr EngineKind kHeldContactMethods[] = {EngineKind::kPcgFem, EngineKind::kCorotationalFem,
                                              EngineKind::kMsdsExplicit, EngineKind::kMsdsImplicit};

TEST(SlidingProbe, FrictionlessSlipPressesAsHardWhereverTheFaceStops) {
  const testing::SlabRegion r = homogeneous_slab();
  const EngineSettings frictionless = with_held_contact(HeldContactModel::kCoulombSlip, 0.0);
  const SlideFigures exact = slide(EngineKind::kExactFem, r);
  for (EngineKind kind : kHeldContactMethods) {
    const SlideFigures slip = slide(kind, r, frictionless);
    ASSERT_GT(slip.force_before_n, 0.1) << engine_key(kind);
    EXPECT_NEAR(slip.force_after_n, slip.force_before_n, 0.03 * slip.force_before_n)
        << engine_key(kind);
    EXPECT_NEAR(slip.largest_move_after_mm, slip.largest_move_before_mm,
                0.03 * slip.largest_move_before_mm)
        << engine_key(kind) << ": the skin slid under the face, not along with it";
    if (kind == EngineKind::kPcgFem) {
      // The same linear FEM and the same contact law as the exact FEM: the same answer.
      EXPECT_NEAR(slip.force_before_n, exact.force_before_n, 0.03 * exact.force_before_n);
      EXPECT_NEAR(slip.force_after_n, exact.force_after_n, 0.03 * exact.force_after_n);
    }
  }
}

// Gel friction (μ 0.1) at this depth, shallower than the face's rounded edge: the face shears the
// skin forward a little; the force may not climb as the stick contact's does. (Pressed deeper,
// the face's side pushes the skin ahead and friction there holds it: settings.hpp.)
TEST(SlidingProbe, GelFrictionBoundsTheDragOfAShallowFace) {
  const testing::SlabRegion r = homogeneous_slab();
  const EngineSettings gel_settings = with_held_contact(HeldContactModel::kCoulombSlip, 0.1);
  for (EngineKind kind : kHeldContactMethods) {
    const SlideFigures gel = slide(kind, r, gel_settings);
    EXPECT_LT(gel.force_after_n, 1.1 * gel.force_before_n) << engine_key(kind);
    EXPECT_LT(gel.largest_move_after_mm, 1.2 * gel.largest_move_before_mm) << engine_key(kind);
  }
}

// The published contact's known limitation, pinned with its figures (2 mm deep, 30 mm slid: PCG
// FEM 0.42 -> 1.31 N and the largest move 2.0 -> 6.5 mm; explicit and implicit MSDS 2.7 -> 5.2 /
// 5.0 N, 2.0 -> 3.7 / 3.8 mm).
TEST(SlidingProbe, TheStickContactPressesHarderTheFartherTheFaceSlides) {
  const testing::SlabRegion r = homogeneous_slab();
  const EngineSettings stick_settings = with_held_contact(HeldContactModel::kStick, 0.0);
  for (EngineKind kind : kHeldContactMethods) {
    const SlideFigures stick = slide(kind, r, stick_settings);
    EXPECT_GT(stick.force_after_n, 1.5 * stick.force_before_n) << engine_key(kind);
    EXPECT_GT(stick.largest_move_after_mm, 1.5 * stick.largest_move_before_mm)
        << engine_key(kind) << ": the skin went along with the face";
  }
}

// Pressed deeper than the face's rounded edge (4 mm) the MSDS catches nodes inside the tissue
// too, while its springs lag; slid along the face, one passed the surface node over it and the
// tets between stayed folded, every later frame refused (128 tets at once). Only the nodes the
// probe can reach slide: no frame refused, the force within 60 % of where it started (measured
// 4.20 -> 6.41 and 4.06 -> 5.95 N; the frictionless exact FEM keeps 0.76 N, docs/accuracy.md).
TEST(SlidingProbe, TheMsdsSlidesADeepFaceWithoutFoldingTheSkin) {
  const testing::SlabRegion r = homogeneous_slab(12);
  for (EngineKind kind : {EngineKind::kMsdsExplicit, EngineKind::kMsdsImplicit}) {
    const SlideFigures deep = slide(kind, r, EngineSettings{}, 4.0);
    EXPECT_EQ(deep.refused_frames, 0) << engine_key(kind);
    EXPECT_LT(deep.force_after_n, 1.6 * deep.force_before_n) << engine_key(kind);
  }
}

// Deeper than the face's rounded edge (4 mm, 22 mm slab) the face's side meets the skin too. The
// PCG FEM's sliding nodes are solved inside its CG, held along the probe's normal only, as the
// exact FEM holds them: after the slide and 40 frames' settle the two agree (measured 0.77 and
// 0.76 N, 4.03 mm each; with the slide between steps the PCG FEM had been at 1.02 N, 4.64 mm).
TEST(SlidingProbe, ThePcgFemSlidesADeepFaceAsTheExactFemDoes) {
  const testing::SlabRegion r = homogeneous_slab(12);
  const SlideFigures exact = slide(EngineKind::kExactFem, r, EngineSettings{}, 4.0);
  const SlideFigures pcg = slide(EngineKind::kPcgFem, r, EngineSettings{}, 4.0);
  ASSERT_GT(exact.force_before_n, 0.5);
  EXPECT_EQ(pcg.refused_frames, 0);
  EXPECT_NEAR(pcg.force_before_n, exact.force_before_n, 0.03 * exact.force_before_n);
  EXPECT_NEAR(pcg.force_after_n, exact.force_after_n, 0.03 * exact.force_after_n);
  EXPECT_NEAR(pcg.largest_move_after_mm, exact.largest_move_after_mm,
              0.03 * exact.largest_move_after_mm);
}

}  // namespace
}  // namespace ultrasim::sim
