#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "ultrasim/hal/pose_source.hpp"

namespace ultrasim::drivers::sim_probe {

// One pose of a scripted motion. Between keyframes the position is interpolated linearly and the
// orientation by slerp. A non-empty `marker` names the moment (e.g. "pressed"), so a headless run
// can take its screenshots where the script says something is worth seeing.
struct Keyframe {
  hal::TimestampUs time_us = 0;
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  std::string marker;
};

// A simulated probe that plays a keyframed motion. It publishes the same PoseSample a real
// tracker does, so nothing downstream can tell it apart from hardware.
class ScriptedProbe final : public hal::PoseSource {
 public:
  // Keyframes must be in strictly increasing time and hold finite values with unit quaternions;
  // throws std::invalid_argument naming the offending keyframe otherwise. Allocates.
  explicit ScriptedProbe(std::vector<Keyframe> keyframes);

  // The scripted pose at now_us (held at the first/last keyframe outside the script's span).
  // Does not allocate.
  std::optional<hal::PoseSample> latest(hal::TimestampUs now_us) override;
  std::string_view name() const override { return "scripted"; }

  hal::TimestampUs duration_us() const { return keyframes_.back().time_us; }
  const std::vector<Keyframe>& keyframes() const { return keyframes_; }

 private:
  std::vector<Keyframe> keyframes_;
  std::uint32_t sequence_ = 0;
};

// The standard headless session over a case: hover above the skin (no contact), touch down at
// `start`, sweep to `end`, return to the middle, press `press_depth_mm` into the skin along +z,
// hold, release and lift. Markers: "lifted", "sweep-start", "sweep-end", "rest", "pressed",
// "released". `contact_depth_mm` is the light pressure of a probe resting on the skin.
std::vector<Keyframe> sweep_press_script(const Eigen::Vector3d& start_mm,
                                         const Eigen::Vector3d& end_mm, double press_depth_mm,
                                         double contact_depth_mm = 0.5);

}  // namespace ultrasim::drivers::sim_probe
