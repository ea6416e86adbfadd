#include "ultrasim/kiosk/refused_press.hpp"

#include <Eigen/Geometry>
#include <algorithm>

namespace ultrasim::kiosk {

const hal::PoseSample& RefusedPress::pose_for(const hal::PoseSample& probe) {
  probe_pose_tried_ = false;
  if (!refused_ || !taken_) {
    attempt_ = Attempt::kProbe;
    pose_ = probe;
    return pose_;
  }
  if (probe.position_mm.z() <
      std::max(refused_depth_mm_, taken_->position_mm.z()) - kRetryAfterLiftMm) {
    // Lifted (above where it was refused, or where the tissue is pressed if deeper): a probe on
    // its way up, or off the skin, must not leave the tissue pressed deeper.
    attempt_ = Attempt::kToward;
    pose_ = probe;
    probe_pose_tried_ = true;
  } else if (++frames_since_try_ >= kRetryEveryFrames) {
    attempt_ = Attempt::kToward;
    pose_ = toward_probe(probe);
  } else {
    attempt_ = Attempt::kHeld;
    pose_ = probe;
    pose_.position_mm = taken_->position_mm;
    pose_.orientation = taken_->orientation;
  }
  return pose_;
}

hal::PoseSample RefusedPress::toward_probe(const hal::PoseSample& probe) {
  const double distance_mm = (probe.position_mm - taken_->position_mm).norm();
  const double angle_rad = taken_->orientation.angularDistance(probe.orientation);
  const double reach = distance_mm <= kNearMm && angle_rad <= kNearRad ? 1.0 : reach_;
  probe_pose_tried_ = reach >= 1.0;
  if (probe_pose_tried_) return probe;
  hal::PoseSample pose = probe;
  pose.position_mm = taken_->position_mm + reach * (probe.position_mm - taken_->position_mm);
  pose.orientation = taken_->orientation.slerp(reach, probe.orientation);
  return pose;
}

void RefusedPress::record(PressVerdict verdict) {
  const bool probes_own_pose = attempt_ == Attempt::kProbe || probe_pose_tried_;
  if (verdict == PressVerdict::kOutOfTime) {
    // Every frame out of time on the same press would keep the last good shape for as long as
    // the probe stays: once is bad luck, twice a refusal.
    verdict = !probes_own_pose || ++probe_out_of_time_ > 1 ? PressVerdict::kRefused
                                                           : PressVerdict::kUndecided;
  }
  if (verdict != PressVerdict::kUndecided || !probes_own_pose) probe_out_of_time_ = 0;
  if (verdict == PressVerdict::kRefused && probes_own_pose) {
    // The probe's own pose refused (at first, after a lift, or reached by the tries): held from
    // here, where the tissue last took it.
    if (!taken_) return;
    refused_ = true;
    refused_depth_mm_ = pose_.position_mm.z();
    frames_since_try_ = 0;
    reach_ = kFirstReach;
    backed_off_mm_ = 0.0;
    last_try_taken_ = false;
    return;
  }
  switch (attempt_) {
    case Attempt::kProbe:
      if (verdict == PressVerdict::kTaken) taken_ = pose_;
      return;
    case Attempt::kToward:
      if (verdict == PressVerdict::kTaken) {
        taken_ = pose_;
        backed_off_mm_ = 0.0;
        if (probe_pose_tried_) {
          refused_ = false;  // caught up
          return;
        }
        reach_ = std::min(kGrowth * reach_, 1.0);
        frames_since_try_ = kRetryEveryFrames;  // the next frame goes on
        last_try_taken_ = true;
        return;
      }
      if (verdict == PressVerdict::kRefused) reach_ = std::max(0.5 * reach_, kLeastReach);
      // A try refused after one taken tries half as far the next frame; after another refused
      // (or none decided), the tissue waits held.
      frames_since_try_ =
          last_try_taken_ && verdict == PressVerdict::kRefused ? kRetryEveryFrames : 0;
      last_try_taken_ = false;
      return;
    case Attempt::kHeld:
      if (verdict == PressVerdict::kTaken) {
        backed_off_mm_ = 0.0;
      } else if (verdict == PressVerdict::kRefused && backed_off_mm_ < kMostBackOffMm) {
        // The held pose itself is refused: back off along the beam, each step as far as all
        // before it and the first (0.5, 1, 2, 4, 8, then 8 mm at a time).
        const double step_mm = std::min(
            {backed_off_mm_ + kFirstBackOffMm, kLargestBackOffMm, kMostBackOffMm - backed_off_mm_});
        taken_->position_mm -= step_mm * (taken_->orientation * Eigen::Vector3d::UnitZ());
        backed_off_mm_ += step_mm;
      }
      return;
  }
}

PressVerdict verdict_of(const sim::EngineStepStats& step) {
  switch (step.recovery) {
    case sim::Recovery::kKeptLastGood:
      // Cut short, as a refusal: the methods that halve their steps (MSDS, corotational FEM)
      // say the budget ran out before the halved ones were tried. The PCG FEM's CG says only
      // that its iterations were cut (the usual in the kiosk); its refusal then counts from the
      // second frame in a row, a frame later.
      return step.cut_short ? PressVerdict::kOutOfTime : PressVerdict::kRefused;
    case sim::Recovery::kReset:
      return PressVerdict::kUndecided;
    case sim::Recovery::kNone:
    case sim::Recovery::kSubstepped:
      break;
  }
  return PressVerdict::kTaken;
}

}  // namespace ultrasim::kiosk
