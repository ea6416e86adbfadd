#pragma once

#include <Eigen/Geometry>
#include <optional>

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::fiducial {

// The 1€ filter (Casiez, Roussel and Vogel, CHI 2012) on a rigid pose: a low-pass whose cutoff
// rises with speed, so a probe held still does not jitter and a moving one does not lag.
struct PoseFilterSettings {
  // Cutoff at rest, Hz: lower = steadier when still, more lag on slow moves.
  double min_cutoff_hz = 1.5;
  // Added cutoff per unit of speed: Hz per mm/s (position) and per °/s (orientation). Higher =
  // less lag when moving fast.
  double position_beta = 0.1;
  double orientation_beta = 0.1;
  // Cutoff of the speed estimate itself, Hz.
  double speed_cutoff_hz = 1.0;
};

class PoseFilter {
 public:
  explicit PoseFilter(const PoseFilterSettings& settings = {}) : settings_(settings) {}

  // The filtered pose after a measurement taken at timestamp_us (the first one passes
  // unchanged; a timestamp not after the last one replaces it unfiltered). No allocation.
  Eigen::Isometry3d update(const Eigen::Isometry3d& measured, hal::TimestampUs timestamp_us);

  // Forget the history: the next measurement passes unchanged (after a lost track).
  void reset() { last_.reset(); }

  const std::optional<Eigen::Isometry3d>& last() const { return last_; }

 private:
  PoseFilterSettings settings_;
  std::optional<Eigen::Isometry3d> last_;
  hal::TimestampUs last_us_ = 0;
  double position_speed_ = 0.0;     // mm/s, filtered
  double orientation_speed_ = 0.0;  // °/s, filtered
};

}  // namespace ultrasim::drivers::fiducial
