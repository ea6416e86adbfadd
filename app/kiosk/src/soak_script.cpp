#include "ultrasim/kiosk/soak_script.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace ultrasim::kiosk {

namespace {

// Uniform in [lo, hi) from the generator's raw bits: the same numbers from every standard
// library (std::uniform_real_distribution's are not specified).
double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

hal::TimestampUs at(double seconds) {
  return static_cast<hal::TimestampUs>(seconds * 1e6);
}

}  // namespace

Script soak_script(const config::CaseScan& scan, double depth_mm, double duration_s,
                   std::uint64_t seed) {
  if (!(duration_s >= kSoakWarmUpS)) {
    throw std::invalid_argument("soak: the duration must be at least " +
                                std::to_string(kSoakWarmUpS) + " s (the warm-up)");
  }
  std::mt19937_64 rng(seed);
  const Eigen::Vector3d start(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]);
  const Eigen::Vector3d end(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2]);
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const double max_press_mm = 1.5 * scan.press_depth_mm;

  Script script;
  double t = 0.0;
  double along = 0.5;  // position on the scan line, 0 = start, 1 = end
  double press_mm = 0.0;
  Eigen::Quaterniond tilt = Eigen::Quaterniond::Identity();
  const auto key = [&](double seconds, double lift_mm = 0.0) {
    t += seconds;
    const Eigen::Vector3d p = start + along * (end - start) + (press_mm - lift_mm) * down;
    script.keyframes.push_back({at(t), p, tilt, ""});
  };
  key(0.0, 5.0);  // above the skin
  key(0.5);       // touching

  // Warm-up: press, and switch once through every live method while holding, ending on the
  // kiosk's default (the first).
  press_mm = 0.5 * scan.press_depth_mm;
  key(0.5);
  const double per_method = (kSoakWarmUpS - 1.0) / (std::size(kLiveMethods) + 1);
  for (std::size_t i = 0; i <= std::size(kLiveMethods); ++i) {
    script.controls.push_back({at(t), false, depth_mm, kLiveMethods[i % std::size(kLiveMethods)]});
    key(per_method);
  }

  // The trainee at random until the time is up.
  bool frozen = false;
  while (t < duration_s) {
    const double seconds = uniform(rng, 0.3, 2.0);
    const double pick = uniform(rng, 0.0, 1.0);
    if (pick < 0.30) {  // sweep
      along = uniform(rng, 0.0, 1.0);
      key(seconds);
    } else if (pick < 0.55) {  // press or ease
      press_mm = uniform(rng, 0.0, max_press_mm);
      key(seconds);
    } else if (pick < 0.65) {  // lift off and come back
      key(0.5 * seconds, 5.0);
      key(0.5 * seconds);
    } else if (pick < 0.75) {  // tilt, up to 15° about either horizontal axis
      const Eigen::Vector3d axis(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), 0.0);
      const double angle = uniform(rng, -15.0, 15.0) * std::acos(-1.0) / 180.0;
      tilt = axis.norm() > 1e-3 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()))
                                : Eigen::Quaterniond::Identity();
      key(seconds);
    } else if (pick < 0.85) {  // hold
      key(seconds);
    } else if (pick < 0.93) {  // freeze or unfreeze
      frozen = !frozen;
      script.controls.push_back({at(t), frozen, depth_mm, {}});
      key(seconds);
    } else {  // switch method
      const auto m = static_cast<std::size_t>(uniform(rng, 0.0, std::size(kLiveMethods)));
      script.controls.push_back({at(t), frozen, depth_mm, kLiveMethods[m]});
      key(seconds);
    }
  }
  script.keyframes.back().marker = "end";
  return script;
}

}  // namespace ultrasim::kiosk
