#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::hal {

enum class PoseHealth : std::uint8_t {
  kOk,     // fresh sample from a working source
  kStale,  // source alive but no new sample within its expected period
  kFault,  // source reports an error; the pose must not be used
};

// One probe pose as a tracker delivers it.
//
// Probe frame: origin at the centre of the transducer face; +x along the array (lateral),
// +y across the array (elevational, normal to the image plane), +z along the beam into tissue
// (axial). position_mm and orientation map the probe frame into patient (case) space, in mm.
struct PoseSample {
  TimestampUs timestamp_us = 0;  // when the pose was measured (source clock, monotonic)
  std::uint32_t sequence = 0;    // increments per sample; gaps mean dropped samples
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  PoseHealth health = PoseHealth::kOk;
};

// True when every number in the sample is finite and the orientation is a unit quaternion
// (within 1e-3). A sample that fails this must never reach the simulation or the screen.
inline bool is_valid(const PoseSample& sample) {
  if (!sample.position_mm.allFinite() || !sample.orientation.coeffs().allFinite()) return false;
  const double norm = sample.orientation.norm();
  return norm > 1.0 - 1e-3 && norm < 1.0 + 1e-3;
}

}  // namespace ultrasim::hal
