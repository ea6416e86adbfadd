#include "ultrasim/kiosk/session.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>

#include "tiny_case.hpp"

namespace ultrasim::kiosk {
namespace {

hal::PoseSample pose_at(double depth_mm) {
  hal::PoseSample s;
  s.position_mm = {0.0, 0.0, depth_mm};
  return s;
}

class SessionTest : public ::testing::Test {
 protected:
  SessionTest() : tissue_(load_tissue_case(files_.dir())) {
    settings_.bscan.width_px = 64;
    settings_.bscan.height_px = 64;
    settings_.fem.pcg_iterations_per_frame = 200;
  }
  testing::TinyCase files_;
  TissueCase tissue_;
  config::AppSettings settings_;
  hal::ManualClock clock_;
};

TEST_F(SessionTest, NoPoseYetMeansNoContactAndABlankImage) {
  Session session(tissue_, settings_, clock_);
  const FrameOutcome outcome = session.update(std::nullopt);
  EXPECT_TRUE(outcome.pose_rejected);
  EXPECT_FALSE(outcome.in_contact);
  for (auto p : session.bscan()) EXPECT_EQ(p, settings_.bscan.background_grey);
  EXPECT_FALSE(session.frame_input(0).bscan.in_contact);
}

TEST_F(SessionTest, PressingShowsTissueAndPushesTheSkinDown) {
  Session session(tissue_, settings_, clock_);
  FrameOutcome outcome;
  for (int f = 0; f < 10; ++f) outcome = session.update(pose_at(0.3 * f));
  EXPECT_TRUE(outcome.in_contact);
  EXPECT_GT(outcome.fem.contact_force_n, 0.0);
  const auto bright = std::count_if(session.bscan().begin(), session.bscan().end(),
                                    [](std::uint8_t p) { return p > 40; });
  EXPECT_GT(bright, 64 * 64 / 4);
  const render::FrameInput frame = session.frame_input(9);
  EXPECT_TRUE(frame.bscan.in_contact);
  EXPECT_EQ(frame.mesh.node_positions_mm.size(), 3u * 125u);
  float max_displacement = 0;
  for (float d : frame.mesh.node_displacement_mm) max_displacement = std::max(max_displacement, d);
  EXPECT_NEAR(max_displacement, 2.7, 0.05);
}

TEST_F(SessionTest, BadSamplesAreDroppedAndTheLastGoodPoseKept) {
  Session session(tissue_, settings_, clock_);
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
  Session session(tissue_, settings_, clock_);
  for (int f = 0; f < 5; ++f) session.update(pose_at(1.0));
  ASSERT_TRUE(session.in_contact());
  FrameOutcome outcome;
  for (int f = 0; f < 5; ++f) outcome = session.update(pose_at(-5.0));
  EXPECT_FALSE(outcome.in_contact);
  for (auto p : session.bscan()) EXPECT_EQ(p, settings_.bscan.background_grey);
}

}  // namespace
}  // namespace ultrasim::kiosk
