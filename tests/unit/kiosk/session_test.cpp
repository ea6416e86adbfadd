#include "ultrasim/kiosk/session.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <limits>

#include "tiny_case.hpp"

namespace ultrasim::kiosk {
namespace {

using SessionTest = testing::TinyCaseTest;
using testing::pose_at;

TEST_F(SessionTest, NoPoseYetMeansNoContactAndABlankImage) {
  Session session(tissue_, settings_, clock_, jobs_);
  const FrameOutcome outcome = session.update(std::nullopt);
  EXPECT_TRUE(outcome.pose_rejected);
  EXPECT_FALSE(outcome.in_contact);
  for (auto p : session.bscan()) EXPECT_EQ(p, settings_.bscan.background_grey);
  EXPECT_FALSE(session.frame_input(0).bscan.in_contact);
}

TEST_F(SessionTest, PressingShowsTissueAndPushesTheSkinDown) {
  Session session(tissue_, settings_, clock_, jobs_);
  FrameOutcome outcome;
  for (int f = 0; f < 10; ++f) outcome = session.update(pose_at(0.3 * f));
  EXPECT_TRUE(outcome.in_contact);
  EXPECT_GT(outcome.sim.contact_force_n, 0.0);
  const auto bright = std::count_if(session.bscan().begin(), session.bscan().end(),
                                    [](std::uint8_t p) { return p > 40; });
  EXPECT_GT(bright, 64 * 64 / 4);
  const render::FrameInput frame = session.frame_input(9);
  EXPECT_TRUE(frame.bscan.in_contact);
  // The view gets the 5×5×5 mesh's surface nodes only (125 less the 27 inside).
  EXPECT_EQ(frame.mesh.node_positions_mm.size(), 3u * 98u);
  for (const auto& level : frame.mesh.line_levels) {
    for (std::uint32_t i : level.line_indices) ASSERT_LT(i, 98u);
  }
  float max_displacement = 0;
  for (float d : frame.mesh.node_displacement_mm) max_displacement = std::max(max_displacement, d);
  EXPECT_NEAR(max_displacement, 2.7, 0.05);
}

TEST_F(SessionTest, TheVeinSurfaceFollowsTheCompressedTissue) {
  ASSERT_EQ(tissue_.structures.size(), 1u);  // the tiny case has a vein only
  EXPECT_EQ(tissue_.structures[0].label, 4);
  Session session(tissue_, settings_, clock_, jobs_);
  session.update(pose_at(-3.0));  // lifted: the surface sits where it was extracted
  const auto at_rest = session.frame_input(0).surfaces;
  ASSERT_EQ(at_rest.size(), 2u);  // the vein, then the skin
  const std::vector<float> rest(at_rest[0].positions_mm.begin(), at_rest[0].positions_mm.end());
  for (std::size_t v = 0; v < rest.size(); v += 3) {
    const auto& p = tissue_.structures[0].rest.vertices_mm[v / 3];
    ASSERT_NEAR(rest[v + 2], p.z(), 1e-4);
  }
  for (int f = 0; f < 10; ++f) session.update(pose_at(0.4 * f));
  const auto pressed = session.frame_input(0).surfaces[0].positions_mm;
  float top_rest = 1e9f, top_pressed = 1e9f;
  for (std::size_t v = 2; v < rest.size(); v += 3) {
    top_rest = std::min(top_rest, rest[v]);
    top_pressed = std::min(top_pressed, pressed[v]);
  }
  EXPECT_GT(top_pressed, top_rest + 0.5f) << "the vein's top is pushed deeper by the probe";
  for (float n : session.frame_input(0).surfaces[0].normals) ASSERT_TRUE(std::isfinite(n));
  // The skin over the tissue dents with it, translucent so the vein shows through.
  const render::SurfaceView& skin = session.frame_input(0).surfaces[1];
  EXPECT_LT(skin.rgba[3], 0.5f);
  float deepest = -1e9f;
  for (std::size_t v = 2; v < skin.positions_mm.size(); v += 3)
    deepest = std::max(deepest, skin.positions_mm[v]);
  EXPECT_GT(deepest, 1.0f) << "the skin under the probe is pressed in";
}

TEST_F(SessionTest, BadSamplesAreDroppedAndTheLastGoodPoseKept) {
  Session session(tissue_, settings_, clock_, jobs_);
  for (int f = 0; f < 10; ++f) session.update(pose_at(2.0));
  const std::vector<std::uint8_t> before(session.bscan().begin(), session.bscan().end());

  const double nan = std::numeric_limits<double>::quiet_NaN();
  hal::PoseSample not_a_number = pose_at(nan);
  hal::PoseSample not_unit = pose_at(5.0);
  not_unit.orientation.coeffs() << 0.0, 0.0, 0.0, 2.0;
  hal::PoseSample faulted = pose_at(6.0);
  faulted.health = hal::PoseHealth::kFault;
  hal::PoseSample infinite = pose_at(std::numeric_limits<double>::infinity());
  for (const auto& bad : {not_a_number, not_unit, faulted, infinite}) {
    const FrameOutcome outcome = session.update(bad);
    EXPECT_TRUE(outcome.pose_rejected);
    EXPECT_TRUE(outcome.in_contact) << "the last good pose still presses";
    const render::FrameInput frame = session.frame_input(0);
    for (float v : frame.mesh.node_positions_mm) ASSERT_TRUE(std::isfinite(v));
    for (float v : frame.probe.probe_to_patient) ASSERT_TRUE(std::isfinite(v));
    const std::vector<std::uint8_t> after(session.bscan().begin(), session.bscan().end());
    EXPECT_EQ(after, before) << "a bad sample must not change the image";
  }
}

TEST_F(SessionTest, LiftingTheProbeEndsContactAndBlanksTheImage) {
  Session session(tissue_, settings_, clock_, jobs_);
  for (int f = 0; f < 5; ++f) session.update(pose_at(1.0));
  ASSERT_TRUE(session.in_contact());
  FrameOutcome outcome;
  for (int f = 0; f < 5; ++f) outcome = session.update(pose_at(-5.0));
  EXPECT_FALSE(outcome.in_contact);
  for (auto p : session.bscan()) EXPECT_EQ(p, settings_.bscan.background_grey);
}

double mean_grey(std::span<const std::uint8_t> image) {
  double sum = 0;
  for (auto p : image) sum += p;
  return sum / static_cast<double>(image.size());
}

TEST_F(SessionTest, GainAndDynamicRangeChangeTheImageOnTheDecibelScale) {
  Session session(tissue_, settings_, clock_, jobs_);
  for (int f = 0; f < 5; ++f) session.update(pose_at(1.0));
  const double neutral = mean_grey(session.bscan());
  BscanControls brighter = session.controls();
  brighter.gain_db = 6.0;
  session.set_controls(brighter);
  session.update(pose_at(1.0));
  EXPECT_NEAR(mean_grey(session.bscan()) - neutral, 25.5, 3.0);  // 6 dB of 60 dB over 255 grey
  BscanControls contrast = session.controls();
  contrast.gain_db = 0.0;
  contrast.dynamic_range_db = 30.0;
  session.set_controls(contrast);
  session.update(pose_at(1.0));
  EXPECT_LT(mean_grey(session.bscan()), neutral) << "the lower 30 dB go black";
}

TEST_F(SessionTest, DepthControlRebuildsTheImageGrid) {
  Session session(tissue_, settings_, clock_, jobs_);
  BscanControls deeper = session.controls();
  EXPECT_EQ(deeper.depth_mm, 16.0);  // the tiny case's probe
  deeper.depth_mm = 12.0;
  session.set_controls(deeper);
  session.update(pose_at(1.0));
  const render::FrameInput frame = session.frame_input(0);
  EXPECT_FLOAT_EQ(frame.bscan.depth_mm, 12.0f);
  EXPECT_FLOAT_EQ(frame.probe.image_depth_mm, 12.0f);
  EXPECT_EQ(frame.bscan.height_px, 64);
}

TEST_F(SessionTest, FreezeHoldsTheImageWhileTheTissueFollowsTheProbe) {
  Session session(tissue_, settings_, clock_, jobs_);
  for (int f = 0; f < 5; ++f) session.update(pose_at(0.5));
  BscanControls frozen = session.controls();
  frozen.frozen = true;
  session.set_controls(frozen);
  const std::vector<std::uint8_t> held(session.bscan().begin(), session.bscan().end());
  FrameOutcome outcome;
  for (int f = 0; f < 5; ++f) outcome = session.update(pose_at(3.0));
  EXPECT_GT(outcome.sim.contact_force_n, 0.0) << "the simulation runs on";
  EXPECT_EQ(std::vector<std::uint8_t>(session.bscan().begin(), session.bscan().end()), held);
  for (int f = 0; f < 3; ++f) session.update(pose_at(-5.0));  // lifted, still frozen
  const render::FrameInput frame = session.frame_input(0);
  EXPECT_TRUE(frame.bscan.frozen);
  EXPECT_TRUE(frame.bscan.in_contact) << "a frozen image of tissue stays shown";
}

TEST_F(SessionTest, ScanLineAcquisitionShowsTheSameTissueAsTheDisplayGrid) {
  Session direct(tissue_, settings_, clock_, jobs_);
  config::AppSettings scanned_settings = settings_;
  scanned_settings.bscan.scan_lines = 48;
  scanned_settings.bscan.samples_per_line = 96;
  Session scanned(tissue_, scanned_settings, clock_, jobs_);
  for (int f = 0; f < 5; ++f) {
    direct.update(pose_at(1.0));
    scanned.update(pose_at(1.0));
  }
  ASSERT_TRUE(scanned.in_contact());
  EXPECT_EQ(scanned.bscan().size(), direct.bscan().size());
  EXPECT_NEAR(mean_grey(scanned.bscan()), mean_grey(direct.bscan()), 3.0);
}

TEST_F(SessionTest, EverySlicerShowsTheSameImage) {
  std::vector<std::vector<std::uint8_t>> images;
  for (auto method : {imaging::SlicerMethod::kReference, imaging::SlicerMethod::kFast,
                      imaging::SlicerMethod::kPublished}) {
    config::AppSettings s = settings_;
    s.bscan.slicer = method;
    s.bscan.gain_db = 4.0;  // the display mapping applies after every slicer alike
    Session session(tissue_, s, clock_, jobs_);
    for (int f = 0; f < 6; ++f) session.update(pose_at(0.4 * f));
    images.emplace_back(session.bscan().begin(), session.bscan().end());
  }
  for (std::size_t m = 1; m < images.size(); ++m)
    for (std::size_t i = 0; i < images[0].size(); ++i)
      ASSERT_LE(std::abs(images[m][i] - images[0][i]), 1) << "method " << m << " pixel " << i;
}

TEST(SessionConvex, EverySlicerShowsTheSameSectorImage) {
  const testing::TinyCase files(testing::tiny_case_toml(
      "[\"z_max\"]", true,
      "kind = \"convex\"\nradius_mm = 12.0\nfan_angle_deg = 70.0\ndepth_mm = 16.0\n"));
  const TissueCase tissue = load_tissue_case(files.dir());
  hal::ManualClock clock;
  hal::InlineJobSystem jobs;
  std::vector<std::vector<std::uint8_t>> images;
  for (auto method : {imaging::SlicerMethod::kReference, imaging::SlicerMethod::kFast,
                      imaging::SlicerMethod::kPublished}) {
    config::AppSettings s;
    s.bscan.width_px = s.bscan.height_px = 64;
    s.bscan.slicer = method;
    Session session(tissue, s, clock, jobs);
    for (int f = 0; f < 6; ++f) session.update(pose_at(0.3 * f));
    ASSERT_TRUE(session.in_contact());
    images.emplace_back(session.bscan().begin(), session.bscan().end());
  }
  // The sector: its top corners are outside the fan, its axis shows tissue.
  EXPECT_EQ(images[0][0], 0);
  EXPECT_EQ(images[0][63], 0);
  EXPECT_GT(images[0][60 * 64 + 32], 30);  // 15 mm deep, below the vein
  for (std::size_t m = 1; m < images.size(); ++m)
    for (std::size_t i = 0; i < images[0].size(); ++i)
      ASSERT_LE(std::abs(images[m][i] - images[0][i]), 1) << "method " << m << " pixel " << i;
}

TEST_F(SessionTest, EveryMethodCanBeSwitchedToLiveAndStartsFromTheShapeShown) {
  Session session(tissue_, settings_, clock_, jobs_);
  EXPECT_EQ(session.method(), sim::EngineKind::kExactFem);  // the default
  for (int f = 0; f < 10; ++f) session.update(pose_at(0.3 * f));
  for (const auto method :
       {sim::EngineKind::kPcgFem, sim::EngineKind::kCorotationalFem, sim::EngineKind::kMsdsExplicit,
        sim::EngineKind::kMsdsImplicit, sim::EngineKind::kExactFem}) {
    const auto before_view = session.frame_input(0).mesh.node_displacement_mm;
    const std::vector<float> before(before_view.begin(), before_view.end());
    session.switch_method(method);
    EXPECT_EQ(session.method(), method);
    // The new method's first frame starts where the old one left the tissue: the skin stays
    // under the probe (no jump back to rest), and the image still shows tissue.
    const FrameOutcome outcome = session.update(pose_at(2.7));
    EXPECT_TRUE(outcome.in_contact) << session.method_name();
    EXPECT_FALSE(outcome.sim.diverged) << session.method_name();
    const auto after = session.frame_input(1).mesh.node_displacement_mm;
    float largest_before = 0, largest_after = 0;
    for (float d : before) largest_before = std::max(largest_before, d);
    for (float d : after) largest_after = std::max(largest_after, d);
    EXPECT_NEAR(largest_after, largest_before, 0.3) << session.method_name();
  }
}

TEST_F(SessionTest, APastDeadlineCutsTheMethodsCgShortAndSaysSo) {
  settings_.sim.method = sim::EngineKind::kPcgFem;
  Session late(tissue_, settings_, clock_, jobs_);
  Session on_time(tissue_, settings_, clock_, jobs_);
  const FrameOutcome cut = late.simulate(pose_at(2.0), clock_.now_us());
  EXPECT_TRUE(cut.sim.cut_short);
  EXPECT_EQ(cut.sim.iterations, 1);
  EXPECT_TRUE(cut.in_contact);
  const FrameOutcome full = on_time.simulate(pose_at(2.0));
  EXPECT_FALSE(full.sim.cut_short);
  EXPECT_GT(full.sim.iterations, 1);
}

// A clock on which every reading takes `tick_us`: the method's work between two of its budget's
// questions is a piece of that length, and so is each reading after a "no".
class TickingClock final : public hal::Clock {
 public:
  explicit TickingClock(hal::TimestampUs tick_us) : tick_us_(tick_us) {}
  hal::TimestampUs now_us() const override { return now_us_.fetch_add(tick_us_) + tick_us_; }

 private:
  hal::TimestampUs tick_us_;
  mutable std::atomic<hal::TimestampUs> now_us_{0};
};

// The implicit MSDS told no in its first step's CG still runs its second step, which asks once
// more: past the deadline on the first frame, by it from the second (the tail kept back).
TEST_F(SessionTest, TheMethodsWorkPastItsFirstNoIsKeptBackFromTheNextFrames) {
  settings_.sim.method = sim::EngineKind::kMsdsImplicit;
  constexpr hal::TimestampUs kTickUs = 100;
  constexpr hal::TimestampUs kShareUs = 1000;
  TickingClock clock(kTickUs);
  Session session(tissue_, settings_, clock, jobs_);
  for (int f = 0; f < 10; ++f) {
    const hal::TimestampUs deadline = clock.now_us() + kShareUs;
    const FrameOutcome outcome = session.simulate(pose_at(2.0 + 0.1 * f), deadline);
    const hal::TimestampUs end = clock.now_us() - kTickUs;  // this reading's own tick is not work
    ASSERT_TRUE(outcome.sim.cut_short) << "frame " << f;
    if (f == 0) {
      EXPECT_GT(end, deadline);
    } else {
      EXPECT_LE(end, deadline) << "frame " << f;
      EXPECT_GE(outcome.sim.iterations, 2) << "frame " << f;  // one a step at least
    }
  }
}

// The tiny case on a 13 × 9 × 9 grid split in three along x: the stitchable methods run stitched,
// the others are refused, and a past deadline steps only the sub-volumes the probe may touch.
class StitchedSessionTest : public ::testing::Test {
 protected:
  static std::string split_toml(const std::string& split) {
    std::string toml = testing::tiny_case_toml();
    const std::string nodes = "nodes = [5, 5, 5]";
    toml.replace(toml.find(nodes), nodes.size(), "nodes = [13, 9, 9]\n" + split);
    return toml;
  }
  StitchedSessionTest()
      : stitched_files_(split_toml("sub_volumes = [3, 1, 1]"), "stitched"),
        one_piece_files_(split_toml(""), "one_piece"),
        stitched_(load_tissue_case(stitched_files_.dir())),
        one_piece_(load_tissue_case(one_piece_files_.dir())) {
    settings_.bscan.width_px = 64;
    settings_.bscan.height_px = 64;
    settings_.sim.method = sim::EngineKind::kMsdsImplicit;
  }
  static float largest_displacement(const Session& session) {
    const auto d = session.frame_input(0).mesh.node_displacement_mm;
    return *std::max_element(d.begin(), d.end());
  }
  testing::TinyCase stitched_files_, one_piece_files_;
  TissueCase stitched_, one_piece_;
  config::AppSettings settings_;
  hal::ManualClock clock_;
  hal::InlineJobSystem jobs_;
};

TEST_F(StitchedSessionTest, StitchableMethodsRunStitchedAndMatchOnePiece) {
  Session stitched(stitched_, settings_, clock_, jobs_);
  Session one_piece(one_piece_, settings_, clock_, jobs_);
  ASSERT_EQ(stitched_.settings.mesh.sub_volumes, (std::array<int, 3>{3, 1, 1}));
  EXPECT_EQ(stitched.method_name(), "stitched MSDS implicit Euler (3 sub-volumes)");
  FrameOutcome outcome;
  for (int f = 0; f < 60; ++f) {
    outcome = stitched.update(pose_at(std::min(2.0, 0.2 * f)));
    one_piece.update(pose_at(std::min(2.0, 0.2 * f)));
  }
  ASSERT_TRUE(outcome.stitch.has_value());
  EXPECT_TRUE(outcome.in_contact);
  // Seams under the face's rounded rim on a 1.7 mm grid: ~0.11 mm apart before the midpoint
  // display (on the 2 mm benchmark region away from the rim, ≤ 0.07 mm: docs/accuracy.md).
  EXPECT_LT(outcome.stitch->max_gap_mm, 0.2);
  EXPECT_NEAR(largest_displacement(stitched), largest_displacement(one_piece),
              0.02 * largest_displacement(one_piece));
  // The exact FEM cannot be stitched: refused, naming the case, and nothing changes.
  EXPECT_FALSE(method_runs_on(stitched_, sim::EngineKind::kExactFem));
  EXPECT_TRUE(method_runs_on(one_piece_, sim::EngineKind::kExactFem));
  try {
    stitched.switch_method(sim::EngineKind::kExactFem);
    FAIL() << "the exact FEM was built on a split case";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("exact cannot run on case 'tiny'"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(stitched.method(), sim::EngineKind::kMsdsImplicit);
  EXPECT_TRUE(stitched.update(pose_at(2.0)).stitch.has_value());
}

// The corotational FEM takes anchor springs too: it runs stitched, switched to live.
TEST_F(StitchedSessionTest, TheCorotationalFemRunsStitchedAndMatchesOnePiece) {
  EXPECT_TRUE(method_runs_on(stitched_, sim::EngineKind::kCorotationalFem));
  settings_.sim.method = sim::EngineKind::kCorotationalFem;
  Session stitched(stitched_, settings_, clock_, jobs_);
  Session one_piece(one_piece_, settings_, clock_, jobs_);
  EXPECT_EQ(stitched.method_name(), "stitched corotational FEM (3 sub-volumes)");
  for (int f = 0; f < 60; ++f) {
    stitched.update(pose_at(std::min(2.0, 0.2 * f)));
    one_piece.update(pose_at(std::min(2.0, 0.2 * f)));
  }
  const FrameOutcome outcome = stitched.update(pose_at(2.0));
  one_piece.update(pose_at(2.0));
  ASSERT_TRUE(outcome.stitch.has_value());
  EXPECT_TRUE(outcome.in_contact);
  EXPECT_LT(outcome.stitch->max_gap_mm, 0.2);
  EXPECT_NEAR(largest_displacement(stitched), largest_displacement(one_piece),
              0.02 * largest_displacement(one_piece));
}

TEST_F(StitchedSessionTest, APastDeadlineStepsOnlyTheTouchedSubVolumes) {
  Session session(stitched_, settings_, clock_, jobs_);
  // At x = -14 mm the 16 mm face reaches the first sub-volume only; its neighbour is due but
  // must wait, and the third, at rest, sleeps.
  hal::PoseSample pose = pose_at(1.0);
  pose.position_mm.x() = -14.0;
  const FrameOutcome late = session.simulate(pose, clock_.now_us());
  ASSERT_TRUE(late.stitch.has_value());
  EXPECT_EQ(late.stitch->sub_volumes_stepped, late.stitch->sub_volumes_touched);
  EXPECT_EQ(late.stitch->sub_volumes_touched, 1);
  EXPECT_EQ(late.stitch->sub_volumes_deferred, 1);
  EXPECT_EQ(late.stitch->sub_volumes_asleep, 1);
  const FrameOutcome on_time = session.simulate(pose);
  EXPECT_GT(on_time.stitch->sub_volumes_stepped, on_time.stitch->sub_volumes_touched);
}

// A press its method refuses (here seams opening past a tight [stitching] refuse_gap_mm) holds
// the tissue where it last took the probe, and tries part of the way on: the tissue follows as
// deep as the method takes it instead of staying at the depth of the first refusal (where it
// stayed while the probe was held, before RefusedPress). The springs alone: with the seams'
// remembered loads this press keeps its seams within the bound and is never refused (12.1 N at
// frame 120).
TEST_F(StitchedSessionTest, ARefusedPressIsFollowedAsDeepAsTheMethodTakesIt) {
  settings_.stitching.refuse_gap_mm = 0.06;
  settings_.stitching.seam_load_rate = 0.0;
  // The other methods' seams (20 E, anchored at the twins' places): the implicit MSDS's own
  // (40 E, led) keep this press's seams within the bound longer (11.6 N at frame 120 against
  // 10.6 at frame 40).
  settings_.stitching.implicit_msds_spring_stiffness_per_modulus_mm = 20.0;
  settings_.stitching.implicit_msds_seam_lead = 0.0;
  // One exchange a frame: with two the seams stay within the bound until 5.9 N (frame 10) and the
  // held press follows from 4.8 N (frame 40) to 6.1 N (frame 110).
  settings_.stitching.implicit_msds_exchanges_per_frame = 1;
  Session session(stitched_, settings_, clock_, jobs_);
  double force_at_40 = 0.0;
  int held = 0;
  FrameOutcome outcome;
  for (int f = 0; f < 120; ++f) {
    outcome = session.simulate(pose_at(std::min(3.0, 0.1 * f)));
    held += outcome.probe_held;
    if (outcome.probe_held) {
      ASSERT_TRUE(outcome.in_contact) << "held where refused: the probe presses, an image shows";
    }
    ASSERT_TRUE(outcome.stitch.has_value());
    if (!outcome.sim.diverged) {
      ASSERT_LE(outcome.stitch->max_gap_mm, 0.06);
    }
    if (f == 40) force_at_40 = outcome.sim.contact_force_n;
  }
  EXPECT_GT(held, 60) << "the press was refused and held";
  EXPECT_TRUE(outcome.in_contact);
  // The probe at 3 mm since frame 30: 2.72 N at frame 40, 5.77 N at 120 (2.64 N before).
  EXPECT_GT(outcome.sim.contact_force_n, 1.5 * force_at_40);
}

TEST_F(SessionTest, OutOfRangeControlsAreRefusedAndChangeNothing) {
  Session session(tissue_, settings_, clock_, jobs_);
  const BscanControls before = session.controls();
  BscanControls bad = before;
  bad.gain_db = 90.0;
  EXPECT_THROW(session.set_controls(bad), std::invalid_argument);
  bad = before;
  bad.depth_mm = std::nan("");
  EXPECT_THROW(session.set_controls(bad), std::invalid_argument);
  bad = before;
  bad.tgc_db[3] = -31.0;
  EXPECT_THROW(session.set_controls(bad), std::invalid_argument);
  EXPECT_EQ(session.controls().gain_db, before.gain_db);
  EXPECT_EQ(session.controls().depth_mm, before.depth_mm);
}

}  // namespace
}  // namespace ultrasim::kiosk
