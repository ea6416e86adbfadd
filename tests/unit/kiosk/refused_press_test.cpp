#include "ultrasim/kiosk/refused_press.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <functional>
#include <utility>

namespace ultrasim::kiosk {
namespace {

hal::PoseSample probe_at(double y_mm, double depth_mm,
                         const Eigen::Quaterniond& tilt = Eigen::Quaterniond::Identity()) {
  hal::PoseSample s;
  s.position_mm = {0.0, y_mm, depth_mm};
  s.orientation = tilt;
  return s;
}

// A method that takes a pose when `takes(pose, last taken pose)` says so, as the session asks
// it: the pose RefusedPress gives for the probe's, then the verdict.
struct Method {
  using Rule = std::function<bool(const hal::PoseSample&, const hal::PoseSample&)>;
  explicit Method(Rule rule) : takes(std::move(rule)) {}
  Rule takes;
  hal::PoseSample shape;  // the pose its tissue was last pressed with
  int refused = 0;
  int frames = 0;

  const hal::PoseSample& frame(RefusedPress& press, const hal::PoseSample& probe) {
    const hal::PoseSample& pose = press.pose_for(probe);
    ++frames;
    if (takes(pose, shape)) {
      shape = pose;
      press.record(PressVerdict::kTaken);
    } else {
      ++refused;
      press.record(PressVerdict::kRefused);
    }
    return pose;
  }
};

Method deepest(double limit_mm) {
  return Method([limit_mm](const hal::PoseSample& p, const hal::PoseSample&) {
    return p.position_mm.z() <= limit_mm;
  });
}

TEST(RefusedPress, ATakenPressIsTheProbesOwnPose) {
  RefusedPress press;
  Method method = deepest(100.0);
  for (int f = 0; f < 30; ++f) {
    const hal::PoseSample probe = probe_at(0.3 * f, 0.2 * f);
    const hal::PoseSample pose = method.frame(press, probe);
    EXPECT_FALSE(press.holding());
    EXPECT_EQ(pose.position_mm, probe.position_mm);
  }
  EXPECT_EQ(method.refused, 0);
}

// The probe goes 10 mm deep; the method takes 4.3 mm at most. The tissue is held at the last
// depth it took, a few tries a second go part of the way, and it ends as deep as the method
// goes, never deeper, with a refused frame a try.
TEST(RefusedPress, ARefusedPressIsHeldAndFollowedAsDeepAsTheMethodGoes) {
  RefusedPress press;
  Method method = deepest(4.3);
  for (int f = 0; f <= 10; ++f) method.frame(press, probe_at(0.0, f));
  EXPECT_EQ(method.refused, 1);  // 5 mm; then held at 4
  const int refused_before = method.refused;
  int held = 0;
  for (int f = 0; f < 300; ++f) {
    const hal::PoseSample pose = method.frame(press, probe_at(0.0, 10.0));
    held += press.holding();
    ASSERT_LT(pose.position_mm.z(), 10.0 - 1.0);
  }
  EXPECT_EQ(held, 300);
  EXPECT_LE(method.shape.position_mm.z(), 4.3);
  EXPECT_GT(method.shape.position_mm.z(), 4.3 - 0.05);
  // Tries, not every frame: at most two refused in RefusedPress::kRetryEveryFrames frames (a
  // refused try after a taken one goes on at once, half as far). 22 of the 300.
  EXPECT_LE(method.refused - refused_before, 2 * 300 / RefusedPress::kRetryEveryFrames);
}

TEST(RefusedPress, LiftingTheProbeOffTheRefusedDepthTriesItsOwnPoseAtOnce) {
  RefusedPress press;
  Method method = deepest(4.3);
  for (int f = 0; f <= 8; ++f) method.frame(press, probe_at(0.0, f));
  method.frame(press, probe_at(0.0, 8.0));
  ASSERT_TRUE(press.holding());
  // Up by less than RefusedPress::kRetryAfterLiftMm: still held.
  EXPECT_EQ(method.frame(press, probe_at(0.0, 7.7)).position_mm.z(), 4.0);
  // Off the skin: the tissue follows the probe, whatever the tries had reached.
  const hal::PoseSample lifted = probe_at(0.0, -5.0);
  EXPECT_EQ(method.frame(press, lifted).position_mm, lifted.position_mm);
  EXPECT_FALSE(press.holding());
  EXPECT_EQ(method.frame(press, probe_at(0.0, 2.0)).position_mm.z(), 2.0);
  EXPECT_FALSE(press.holding());
}

// The soak's refusal loops: the tissue's unfinished solve crept on under the held probe into a
// shape the method refused, and the held pose was refused every frame for seconds. The held pose
// now backs off along the beam (a tilted probe: along its tilted beam) until the tissue takes it.
TEST(RefusedPress, AHeldPoseTheTissueRefusesBacksOffAlongTheBeam) {
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  RefusedPress press;
  double limit_mm = 4.3;
  Method method([&limit_mm](const hal::PoseSample& p, const hal::PoseSample&) {
    return p.position_mm.z() <= limit_mm;
  });
  for (int f = 0; f <= 5; ++f) method.frame(press, probe_at(0.0, f, tilt));
  ASSERT_EQ(method.shape.position_mm.z(), 4.0);
  limit_mm = 1.2;  // the held shape would now go on into a refused one
  int run = 0, longest_run = 0;
  hal::PoseSample last = method.shape;
  for (int f = 0; f < 10; ++f) {
    const int before = method.refused;
    const hal::PoseSample pose = method.frame(press, probe_at(0.0, 5.0, tilt));
    run = method.refused > before ? run + 1 : 0;
    longest_run = std::max(longest_run, run);
    if (f > 0 && pose.position_mm != last.position_mm) {
      // Backed off along the beam, away from the skin.
      const Eigen::Vector3d move = pose.position_mm - last.position_mm;
      const Eigen::Vector3d beam = tilt * Eigen::Vector3d::UnitZ();
      EXPECT_NEAR(move.normalized().dot(-beam), 1.0, 1e-12);
    }
    last = pose;
  }
  // 4 mm deep, backed off 0.5, 1 and 2 mm along the beam (cos 0.3 of each in depth): 1.0 mm.
  EXPECT_EQ(longest_run, 3);
  EXPECT_NEAR(method.shape.position_mm.z(), 4.0 - 3.5 * std::cos(0.3), 1e-9);
  EXPECT_TRUE(press.holding());
}

// A method that takes no move over 1 mm a frame (a sweep dragging deep tissue): the probe jumps
// 17 mm along the skin. The tries halve until one is taken, then double, and catch up.
TEST(RefusedPress, TriesCatchUpWithAProbeThatMovedTooFarAtOnce) {
  RefusedPress press;
  Method method([](const hal::PoseSample& p, const hal::PoseSample& last) {
    return (p.position_mm - last.position_mm).norm() <= 1.0;
  });
  method.shape = probe_at(0.0, 3.0);
  for (int f = 0; f < 3; ++f) method.frame(press, probe_at(0.0, 3.0));
  const hal::PoseSample moved = probe_at(17.0, 3.0);
  int frames = 0;
  do {
    method.frame(press, moved);
  } while (++frames < 600 && method.shape.position_mm != moved.position_mm);
  EXPECT_EQ(method.shape.position_mm, moved.position_mm);
  EXPECT_FALSE(press.holding());
  EXPECT_LT(frames, 150) << method.refused << " refused";  // 109, 14 refused
}

TEST(RefusedPress, NoVerdictChangesNothing) {
  RefusedPress press;
  Method method = deepest(4.3);
  for (int f = 0; f <= 5; ++f) method.frame(press, probe_at(0.0, f));
  ASSERT_TRUE(method.frame(press, probe_at(0.0, 5.0)).position_mm.z() == 4.0);
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 4.0);
    press.record(PressVerdict::kUndecided);  // out of time, say: no back-off
  }
  // Another method: the probe's own pose next.
  press.reset();
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 5.0);
  EXPECT_FALSE(press.holding());
  press.record(PressVerdict::kRefused);  // refused at once: held where the tissue last took it
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 4.0);
}

// Out of time before smaller steps were tried, a method keeps its last good shape: once is no
// verdict on the probe's pose, but every frame so (a press the method takes only in halved
// steps, which the frame never has time for) kept the tissue still while the probe stayed. The
// second in a row is a refusal; a held pose out of time backs off as a refused one does.
TEST(RefusedPress, OutOfTimeTwiceInARowIsARefusalAndAHeldPoseOutOfTimeBacksOff) {
  RefusedPress press;
  for (int f = 0; f <= 4; ++f) {
    press.pose_for(probe_at(0.0, f));
    press.record(PressVerdict::kTaken);
  }
  press.pose_for(probe_at(0.0, 5.0));
  press.record(PressVerdict::kOutOfTime);
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 5.0) << "tried again";
  EXPECT_FALSE(press.holding());
  press.record(PressVerdict::kOutOfTime);
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 4.0) << "held";
  EXPECT_TRUE(press.holding());
  press.record(PressVerdict::kOutOfTime);
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(),
            4.0 - RefusedPress::kFirstBackOffMm);
  // A reset (no verdict) changes nothing; taken, the held pose stays.
  press.record(PressVerdict::kUndecided);
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(),
            4.0 - RefusedPress::kFirstBackOffMm);
  press.record(PressVerdict::kTaken);
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(),
            4.0 - RefusedPress::kFirstBackOffMm);
}

// Caught up, the tissue follows the probe again: its own pose every frame, wherever it goes.
TEST(RefusedPress, CaughtUpTheTissueFollowsTheProbeAgain) {
  RefusedPress press;
  Method method([](const hal::PoseSample& p, const hal::PoseSample& last) {
    return (p.position_mm - last.position_mm).norm() <= 1.0;
  });
  method.shape = probe_at(0.0, 3.0);
  method.frame(press, probe_at(0.0, 3.0));
  for (int f = 0; f < 600 && method.shape.position_mm.y() != 5.0; ++f) {
    method.frame(press, probe_at(5.0, 3.0));
  }
  ASSERT_EQ(method.shape.position_mm.y(), 5.0);
  for (int f = 1; f <= 5; ++f) {
    const hal::PoseSample probe = probe_at(5.0 + 0.5 * f, 3.0);
    EXPECT_EQ(method.frame(press, probe).position_mm, probe.position_mm);
    EXPECT_FALSE(press.holding());
  }
}

// Up by more than RefusedPress::kRetryAfterLiftMm from the refused depth (0.8 mm here, still in
// the tissue) tries the probe's own pose at once, and the method takes it; refused there, it
// is held again, from that depth.
TEST(RefusedPress, ALiftOfLessThanAMillimetreTriesTheProbesPoseAtOnce) {
  RefusedPress press;
  Method method = deepest(4.3);
  for (int f = 0; f <= 5; ++f) method.frame(press, probe_at(0.0, f));
  ASSERT_EQ(method.refused, 1);
  EXPECT_EQ(method.frame(press, probe_at(0.0, 4.6)).position_mm.z(), 4.0) << "0.4 mm: held";
  EXPECT_EQ(method.frame(press, probe_at(0.0, 4.2)).position_mm.z(), 4.2) << "0.8 mm: tried";
  EXPECT_FALSE(press.holding());
  EXPECT_EQ(method.shape.position_mm.z(), 4.2);
  EXPECT_EQ(method.frame(press, probe_at(0.0, 4.5)).position_mm.z(), 4.5);
  EXPECT_EQ(method.refused, 2);
  EXPECT_EQ(method.frame(press, probe_at(0.0, 4.5)).position_mm.z(), 4.2) << "held again";
  EXPECT_EQ(method.frame(press, probe_at(0.0, 3.9)).position_mm.z(), 3.9) << "0.6 mm up";
}

// The tries took the tissue deeper than the depth first refused (the method takes 8 mm, the
// probe's own 10 mm refused at 5 mm and then at 10): a probe lifted above the tissue's depth is
// followed at once, though still below the depth first refused.
TEST(RefusedPress, AProbeLiftedAboveTheTissuesDepthIsFollowedAtOnce) {
  RefusedPress press;
  double limit_mm = 4.3;
  Method method([&limit_mm](const hal::PoseSample& p, const hal::PoseSample&) {
    return p.position_mm.z() <= limit_mm;
  });
  for (int f = 0; f <= 5; ++f) method.frame(press, probe_at(0.0, f));
  limit_mm = 8.0;
  for (int f = 0; f < 300; ++f) method.frame(press, probe_at(0.0, 10.0));
  ASSERT_GT(method.shape.position_mm.z(), 7.5);
  const hal::PoseSample lifted = probe_at(0.0, 6.0);
  EXPECT_EQ(method.frame(press, lifted).position_mm, lifted.position_mm);
  EXPECT_FALSE(press.holding());
}

TEST(RefusedPress, AnotherMethodStartsItsOutOfTimeCountAfresh) {
  RefusedPress press;
  press.pose_for(probe_at(0.0, 4.0));
  press.record(PressVerdict::kTaken);
  press.pose_for(probe_at(0.0, 5.0));
  press.record(PressVerdict::kOutOfTime);  // once: no verdict
  press.reset();                           // another method
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 5.0);
  press.record(PressVerdict::kOutOfTime);  // its first
  EXPECT_EQ(press.pose_for(probe_at(0.0, 5.0)).position_mm.z(), 5.0) << "not held";
  EXPECT_FALSE(press.holding());
}

// Taken again, a held pose that is then refused backs off from the first step again; and the
// back-offs stop after RefusedPress::kMostBackOffMm in all (a safety bound: it once went on 8 mm
// a frame, 420 mm above the skin after 60 frames,).
TEST(RefusedPress, BackOffsStartSmallAgainAfterATakenFrameAndStopAtTheirBound) {
  RefusedPress press;
  for (int f = 0; f <= 4; ++f) {
    press.pose_for(probe_at(0.0, 20.0 + f));
    press.record(PressVerdict::kTaken);
  }
  press.pose_for(probe_at(0.0, 30.0));
  press.record(PressVerdict::kRefused);
  double z = press.pose_for(probe_at(0.0, 30.0)).position_mm.z();
  ASSERT_EQ(z, 24.0);
  press.record(PressVerdict::kRefused);
  press.pose_for(probe_at(0.0, 30.0));
  press.record(PressVerdict::kRefused);  // 0.5, then 1 mm
  z = press.pose_for(probe_at(0.0, 30.0)).position_mm.z();
  ASSERT_EQ(z, 22.5);
  press.record(PressVerdict::kTaken);
  press.pose_for(probe_at(0.0, 30.0));
  press.record(PressVerdict::kRefused);  // from the first step again
  EXPECT_EQ(press.pose_for(probe_at(0.0, 30.0)).position_mm.z(), 22.0);
  // Refused every frame from here (tries toward the probe too): held poses back off to the bound.
  double highest_held = z;
  for (int f = 0; f < 60; ++f) {
    press.record(PressVerdict::kRefused);
    const hal::PoseSample& pose = press.pose_for(probe_at(0.0, 30.0));
    if (press.holding() && pose.position_mm.z() < 24.0) {
      highest_held = std::min(highest_held, pose.position_mm.z());
    }
  }
  EXPECT_EQ(highest_held, 22.5 - RefusedPress::kMostBackOffMm);
}

TEST(RefusedPress, VerdictsFromTheMethodsStats) {
  sim::EngineStepStats s;
  EXPECT_EQ(verdict_of(s), PressVerdict::kTaken);
  s.diverged = true;
  s.recovery = sim::Recovery::kSubstepped;  // the frame stands, in smaller steps
  EXPECT_EQ(verdict_of(s), PressVerdict::kTaken);
  s.recovery = sim::Recovery::kKeptLastGood;
  EXPECT_EQ(verdict_of(s), PressVerdict::kRefused);
  s.cut_short = true;
  EXPECT_EQ(verdict_of(s), PressVerdict::kOutOfTime);
  s.recovery = sim::Recovery::kReset;
  EXPECT_EQ(verdict_of(s), PressVerdict::kUndecided);
}

}  // namespace
}  // namespace ultrasim::kiosk
