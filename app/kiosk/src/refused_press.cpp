#include "ultrasim/kiosk/refused_press.hpp"

#include <Eigen/Geometry>
#include <algorithm>

namespace ultrasim::kiosk {

const hal::PoseSample& RefusedPress::pose_for(const hal::PoseSample& probe) {
  probe_pose_tried_ = false;
  if (!refused_ || !took_a_pose_) {
    attempt_ = Attempt::kProbe;
    pose_ = probe;
    return pose_;
  }
  if (probe.position_mm.z() < refused_depth_mm_ - kRetryAfterLiftMm) {
    // Lifted: a probe on its way up (or off the skin) must not leave the tissue pressed.
    attempt_ = Attempt::kToward;
    pose_ = probe;
    probe_pose_tried_ = true;
  } else if (++frames_since_try_ >= kRetryEveryFrames) {
    attempt_ = Attempt::kToward;
    pose_ = toward_probe(probe);
  } else {
    attempt_ = Attempt::kHeld;
    pose_ = taken_;
    pose_.timestamp_us = probe.timestamp_us;
    pose_.sequence = probe.sequence;
  }
  return pose_;
}

hal::PoseSample RefusedPress::toward_probe(const hal::PoseSample& probe) {
  const double distance_mm = (probe.position_mm - taken_.position_mm).norm();
  const double angle_rad = taken_.orientation.angularDistance(probe.orientation);
  const double reach = distance_mm <= kNearMm && angle_rad <= kNearRad ? 1.0 : reach_;
  probe_pose_tried_ = reach >= 1.0;
  if (probe_pose_tried_) return probe;
  hal::PoseSample pose = probe;
  pose.position_mm = taken_.position_mm + reach * (probe.position_mm - taken_.position_mm);
  pose.orientation = taken_.orientation.slerp(reach, probe.orientation);
  return pose;
}

void RefusedPress::record(PressVerdict verdict) {
  if (verdict == PressVerdict::kOutOfTime) {
    // Every frame out of time on the same press would keep the last good shape for as long as
    // the probe stays: once is bad luck, twice a refusal.
    const bool probes_own = attempt_ == Attempt::kProbe;
    verdict =
        !probes_own || ++probe_out_of_time_ > 1 ? PressVerdict::kRefused : PressVerdict::kUndecided;
  } else {
    probe_out_of_time_ = 0;
  }
  switch (attempt_) {
    case Attempt::kProbe:
      if (verdict == PressVerdict::kTaken) {
        taken_ = pose_;
        took_a_pose_ = true;
      } else if (verdict == PressVerdict::kRefused && took_a_pose_) {
        refused_ = true;
        refused_depth_mm_ = pose_.position_mm.z();
        frames_since_try_ = 0;
        reach_ = kFirstReach;
        back_off_mm_ = kFirstBackOffMm;
        last_try_taken_ = false;
      }
      return;
    case Attempt::kToward:
      if (verdict == PressVerdict::kTaken) {
        taken_ = pose_;
        back_off_mm_ = kFirstBackOffMm;
        if (probe_pose_tried_) {
          refused_ = false;  // caught up
          return;
        }
        reach_ = std::min(kGrowth * reach_, 1.0);
        frames_since_try_ = kRetryEveryFrames;  // the next frame goes on
        last_try_taken_ = true;
        return;
      }
      if (verdict == PressVerdict::kRefused) {
        if (probe_pose_tried_) refused_depth_mm_ = pose_.position_mm.z();
        reach_ = std::max(0.5 * reach_, kLeastReach);
      }
      // A try refused after one taken tries half as far the next frame; after another refused
      // (or none decided), the tissue waits held.
      frames_since_try_ =
          last_try_taken_ && verdict == PressVerdict::kRefused ? kRetryEveryFrames : 0;
      last_try_taken_ = false;
      return;
    case Attempt::kHeld:
      if (verdict == PressVerdict::kTaken) {
        back_off_mm_ = kFirstBackOffMm;
      } else if (verdict == PressVerdict::kRefused) {
        // The held pose itself is refused: back off along the beam.
        taken_.position_mm -= back_off_mm_ * (taken_.orientation * Eigen::Vector3d::UnitZ());
        back_off_mm_ = std::min(2.0 * back_off_mm_, kLargestBackOffMm);
      }
      return;
  }
}

}  // namespace ultrasim::kiosk
