#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace ultrasim::drivers::sim_probe {

ScriptedProbe::ScriptedProbe(std::vector<Keyframe> keyframes) : keyframes_(std::move(keyframes)) {
  if (keyframes_.empty()) throw std::invalid_argument("scripted probe: no keyframes");
  for (std::size_t i = 0; i < keyframes_.size(); ++i) {
    const Keyframe& k = keyframes_[i];
    const std::string where = "scripted probe: keyframe " + std::to_string(i);
    if (!k.position_mm.allFinite() || !k.orientation.coeffs().allFinite() ||
        std::abs(k.orientation.norm() - 1.0) > 1e-6) {
      throw std::invalid_argument(where +
                                  ": position and orientation must be finite, unit quaternion");
    }
    if (i > 0 && k.time_us <= keyframes_[i - 1].time_us) {
      throw std::invalid_argument(where + ": time_us must increase");
    }
  }
}

std::optional<hal::PoseSample> ScriptedProbe::latest(hal::TimestampUs now_us) {
  hal::PoseSample sample;
  sample.timestamp_us = now_us;
  sample.sequence = sequence_++;
  const auto after =
      std::upper_bound(keyframes_.begin(), keyframes_.end(), now_us,
                       [](hal::TimestampUs t, const Keyframe& k) { return t < k.time_us; });
  if (after == keyframes_.begin() || after == keyframes_.end()) {
    const Keyframe& k = after == keyframes_.begin() ? keyframes_.front() : keyframes_.back();
    sample.position_mm = k.position_mm;
    sample.orientation = k.orientation;
    return sample;
  }
  const Keyframe& a = *(after - 1);
  const Keyframe& b = *after;
  const double s =
      static_cast<double>(now_us - a.time_us) / static_cast<double>(b.time_us - a.time_us);
  sample.position_mm = (1 - s) * a.position_mm + s * b.position_mm;
  sample.orientation = a.orientation.slerp(s, b.orientation);
  return sample;
}

std::vector<Keyframe> sweep_press_script(const Eigen::Vector3d& start_mm,
                                         const Eigen::Vector3d& end_mm, double press_depth_mm,
                                         double contact_depth_mm) {
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();  // patient +z: into the tissue
  const Eigen::Vector3d hover = -5.0 * down;
  const Eigen::Vector3d middle = (start_mm + end_mm) / 2;
  const auto at = [](double seconds) { return static_cast<hal::TimestampUs>(seconds * 1e6); };
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  return {
      {at(0.00), start_mm + hover, level, ""},
      {at(0.25), start_mm + hover, level, "lifted"},
      {at(0.75), start_mm + contact_depth_mm * down, level, ""},
      {at(1.00), start_mm + contact_depth_mm * down, level, "sweep-start"},
      {at(3.00), end_mm + contact_depth_mm * down, level, "sweep-end"},
      {at(3.75), middle + contact_depth_mm * down, level, ""},
      {at(4.25), middle + contact_depth_mm * down, level, "rest"},
      {at(5.75), middle + press_depth_mm * down, level, ""},
      {at(6.50), middle + press_depth_mm * down, level, "pressed"},
      {at(7.25), middle + contact_depth_mm * down, level, ""},
      {at(8.00), middle + contact_depth_mm * down, level, "released"},
  };
}

}  // namespace ultrasim::drivers::sim_probe
