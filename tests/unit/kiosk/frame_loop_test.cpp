// The kiosk's frame loop on the tiny case with a manual clock: every stage runs when the frame
// has time; with no time left the B-scan and the view are skipped and hold their last results,
// while the simulation and the drawing still run every frame; a slow drawing's excess over
// its reserve is told apart from the schedule's.

#include "ultrasim/kiosk/frame_loop.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include "tiny_case.hpp"

namespace ultrasim::kiosk {
namespace {

// Records what each frame showed; drawing costs `cost_us` of manual time.
class RecordingRenderer final : public FrameRenderer {
 public:
  RecordingRenderer(hal::ManualClock& clock, std::int64_t cost_us)
      : clock_(clock), cost_us_(cost_us) {}
  void render(const Session& session, std::int64_t frame_index) override {
    const render::FrameInput frame = session.frame_input(frame_index);
    showed_tissue.push_back(frame.bscan.in_contact);
    node_positions_mm.assign(frame.mesh.node_positions_mm.begin(),
                             frame.mesh.node_positions_mm.end());
    max_node_displacement_mm = 0.0f;
    for (float d : frame.mesh.node_displacement_mm) {
      max_node_displacement_mm = std::max(max_node_displacement_mm, d);
    }
    clock_.advance_us(cost_us_);
  }
  std::vector<bool> showed_tissue;
  std::vector<float> node_positions_mm;
  float max_node_displacement_mm = 0.0f;

 private:
  hal::ManualClock& clock_;
  std::int64_t cost_us_;
};

using FrameLoopTest = testing::TinyCaseTest;
using testing::pose_at;

TEST_F(FrameLoopTest, WithTimeEnoughEveryStageRunsEveryFrame) {
  Session session(tissue_, settings_, clock_, jobs_);
  RecordingRenderer renderer(clock_, 5'000);
  FrameLoop loop(session, renderer, clock_, settings_.frame);
  for (int f = 0; f < 10; ++f) {
    const sched::TickReport r = loop.run_frame(pose_at(0.3 * f));
    EXPECT_EQ(r.tasks_run, 4) << f;
    EXPECT_FALSE(r.deadline_missed) << f;
  }
  EXPECT_TRUE(loop.outcome().in_contact);
  EXPECT_TRUE(renderer.showed_tissue.back());
  EXPECT_NEAR(renderer.max_node_displacement_mm, 2.7, 0.05);  // as SessionTest's press
  for (const char* task :
       {FrameLoop::kSimulation, FrameLoop::kBscan, FrameLoop::kView, FrameLoop::kRender}) {
    ASSERT_NE(loop.scheduler().find(task), nullptr) << task;
    EXPECT_EQ(loop.scheduler().find(task)->runs, 10) << task;
    EXPECT_EQ(loop.scheduler().find(task)->slips, 0) << task;
  }
}

TEST_F(FrameLoopTest, WithNoTimeLeftTheBscanAndViewHoldThenLagButNeverFreeze) {
  Session session(tissue_, settings_, clock_, jobs_);
  RecordingRenderer renderer(clock_, 0);
  sched::FrameBudgetSettings budgets = settings_.frame;
  budgets.render_budget_us = budgets.budget_us;  // drawing reserves the whole frame
  FrameLoop loop(session, renderer, clock_, budgets);
  for (int f = 0; f < 2; ++f) loop.run_frame(pose_at(0.3 * (f + 8)));
  EXPECT_EQ(loop.scheduler().find(FrameLoop::kBscan)->slips, 2);
  EXPECT_EQ(loop.scheduler().find(FrameLoop::kView)->slips, 2);
  // The tissue is pressed, but the screen still shows the last B-scan and view it had: a blank
  // image and the tissue at rest, never an uninitialised mesh.
  EXPECT_TRUE(loop.outcome().in_contact);
  EXPECT_GT(loop.outcome().sim.contact_force_n, 0.0);
  EXPECT_FALSE(renderer.showed_tissue.back());
  EXPECT_EQ(renderer.max_node_displacement_mm, 0.0f);
  const auto& rest = tissue_.mesh.rest_positions_mm;
  const auto& shown = tissue_.view_nodes;  // the surface's nodes: all the view draws
  ASSERT_EQ(renderer.node_positions_mm.size(), 3 * shown.size());
  for (std::size_t v = 0; v < shown.size(); ++v) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(renderer.node_positions_mm[3 * v + a], static_cast<float>(rest[shown[v]][a])) << v;
    }
  }
  // Starved for its limit, each runs anyway: the B-scan every third frame, the view every sixth.
  for (int f = 2; f < 12; ++f) loop.run_frame(pose_at(2.7));
  EXPECT_EQ(loop.scheduler().find(FrameLoop::kSimulation)->runs, 12);
  EXPECT_EQ(loop.scheduler().find(FrameLoop::kRender)->runs, 12);
  const sched::TaskStats& bscan = *loop.scheduler().find(FrameLoop::kBscan);
  EXPECT_EQ(bscan.runs, 4);
  EXPECT_EQ(bscan.forced_runs, 4);
  EXPECT_EQ(bscan.slips, 8);
  const sched::TaskStats& view = *loop.scheduler().find(FrameLoop::kView);
  EXPECT_EQ(view.runs, 2);
  EXPECT_EQ(view.forced_runs, 2);
  EXPECT_TRUE(renderer.showed_tissue.back() || renderer.showed_tissue.end()[-2] ||
              renderer.showed_tissue.end()[-3]);
  EXPECT_NEAR(renderer.max_node_displacement_mm, 2.7, 0.05);
}

}  // namespace
}  // namespace ultrasim::kiosk

namespace ultrasim::kiosk {
namespace {

// Probe to photon: the sample's age when the frame starts plus the frame's own time to its
// presentation; a frame whose sample was refused (the last good pose shown) adds nothing.
TEST_F(FrameLoopTest, ProbeToPhotonCountsTheSamplesAgeAndTheFrame) {
  Session session(tissue_, settings_, clock_, jobs_);
  RecordingRenderer renderer(clock_, 5'000);
  FrameLoop loop(session, renderer, clock_, settings_.frame);
  loop.run_frame(pose_at(0.3), 4'000);
  ASSERT_EQ(loop.probe_to_photon().count(), 1);
  // 4 ms old at the start, then the frame: the manual clock moves only in the renderer.
  EXPECT_EQ(loop.probe_to_photon().max_us(), 9'000);
  hal::PoseSample bad = pose_at(0.3);
  bad.position_mm.x() = std::nan("");
  loop.run_frame(bad, 1'000);
  loop.run_frame(std::nullopt);
  EXPECT_EQ(loop.probe_to_photon().count(), 1);
  loop.run_frame(pose_at(0.3), 40'000);
  EXPECT_EQ(loop.probe_to_photon().count(), 2);
  EXPECT_EQ(loop.probe_to_photon().deadline_misses(), 1);  // 45 ms > 33 ms
}

}  // namespace
}  // namespace ultrasim::kiosk

namespace ultrasim::kiosk {
namespace {

// The frame with the rendering at its reserve: a slow rasteriser's excess over the render's
// budget comes off the frame's time (and only that: a draw inside its reserve counts in full).
TEST_F(FrameLoopTest, TheRenderCappedFrameLeavesOutOnlyTheDrawingsExcess) {
  Session session(tissue_, settings_, clock_, jobs_);
  const std::int64_t reserve_us = settings_.frame.render_budget_us;
  RecordingRenderer slow(clock_, reserve_us + 9'000);
  FrameLoop loop(session, slow, clock_, settings_.frame);
  const sched::TickReport whole = loop.run_frame(pose_at(0.3));
  EXPECT_TRUE(whole.deadline_missed);  // only the manual clock's drawing takes time here
  EXPECT_EQ(whole.duration_us, reserve_us + 9'000);
  EXPECT_EQ(loop.last_frame_render_capped_us(), reserve_us);
  EXPECT_EQ(loop.frame_time_render_capped().deadline_misses(), 0);
  EXPECT_EQ(loop.scheduler().frame_stats().deadline_misses(), 1);

  RecordingRenderer quick(clock_, reserve_us - 1'000);
  FrameLoop fits(session, quick, clock_, settings_.frame);
  const sched::TickReport r = fits.run_frame(pose_at(0.3));
  EXPECT_EQ(fits.last_frame_render_capped_us(), r.duration_us);
  ASSERT_EQ(fits.frame_time_render_capped().count(), 1);
  EXPECT_EQ(fits.frame_time_render_capped().max_us(), r.duration_us);
}

}  // namespace
}  // namespace ultrasim::kiosk
