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

double soak_warm_up_s(std::size_t case_count) {
  return kSoakWarmUpS * static_cast<double>(std::max<std::size_t>(case_count, 1));
}

Script soak_script(std::span<const SoakCase> cases, double duration_s, std::uint64_t seed) {
  if (cases.empty()) throw std::invalid_argument("soak: no case to scan");
  const double warm_up_s = soak_warm_up_s(cases.size());
  if (!(duration_s >= warm_up_s)) {
    throw std::invalid_argument("soak: the duration must be at least " + std::to_string(warm_up_s) +
                                " s (the warm-up)");
  }
  std::mt19937_64 rng(seed);
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();

  Script script;
  double t = 0.0;
  std::size_t current = 0;
  double along = 0.5;  // position on the current case's scan line, 0 = start, 1 = end
  double press_mm = 0.0;
  bool frozen = false;
  Eigen::Quaterniond tilt = Eigen::Quaterniond::Identity();
  const auto scan_point = [&](double along_line) {
    const config::CaseScan& scan = cases[current].scan;
    const Eigen::Vector3d start(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]);
    const Eigen::Vector3d end(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2]);
    return Eigen::Vector3d(start + along_line * (end - start));
  };
  // A keyframe `seconds` after the last: pressed press_mm, or lifted 5 mm above the skin.
  const auto key = [&](double seconds, bool lifted = false) {
    t += seconds;
    const Eigen::Vector3d p = scan_point(along) + (lifted ? -5.0 : press_mm) * down;
    script.keyframes.push_back({at(t), p, tilt, ""});
  };
  // A pick from the case list: lift off on this case, jump above the other's scan line, come
  // down. The session restarts there on the method in use.
  const auto switch_case = [&](std::size_t next, std::optional<sim::EngineKind> method) {
    key(0.25, true);
    current = next;
    along = 0.5;
    press_mm = 0.0;
    tilt = Eigen::Quaterniond::Identity();
    script.controls.push_back(
        {at(t), false, cases[current].depth_mm, method, static_cast<int>(current)});
    frozen = false;
    key(0.05, true);  // lifted, the probe moves over to the new case
    key(0.25);
  };
  key(0.0, true);  // above the skin
  key(0.5);        // touching

  // Warm-up, on every case in turn and the first last (a case's session starts afresh when it
  // is picked, so the engines built on it before would be gone): press, and switch once through
  // every live method while holding, ending on the kiosk's default (the first).
  for (std::size_t visit = 0; visit < cases.size(); ++visit) {
    const std::size_t c = (visit + 1) % cases.size();
    if (c != current) switch_case(c, kLiveMethods[0]);
    press_mm = 0.5 * cases[current].scan.press_depth_mm;
    key(0.5);
    const double per_method = (kSoakWarmUpS - 1.0) / (std::size(kLiveMethods) + 1);
    for (std::size_t i = 0; i <= std::size(kLiveMethods); ++i) {
      script.controls.push_back(
          {at(t), false, cases[current].depth_mm, kLiveMethods[i % std::size(kLiveMethods)], {}});
      key(per_method);
    }
  }
  t = std::max(t, warm_up_s);

  // The trainee at random until the time is up.
  while (t < duration_s) {
    const double seconds = uniform(rng, 0.3, 2.0);
    const double pick = uniform(rng, 0.0, 1.0);
    const double depth_mm = cases[current].depth_mm;
    if (pick < 0.30) {  // sweep
      along = uniform(rng, 0.0, 1.0);
      key(seconds);
    } else if (pick < 0.55) {  // press or ease
      press_mm = uniform(rng, 0.0, 1.5 * cases[current].scan.press_depth_mm);
      key(seconds);
    } else if (pick < 0.65) {  // lift off and come back
      key(0.5 * seconds, true);
      key(0.5 * seconds);
    } else if (pick < 0.75) {  // tilt, up to 15° about either horizontal axis
      const Eigen::Vector3d axis(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), 0.0);
      const double angle = uniform(rng, -15.0, 15.0) * std::acos(-1.0) / 180.0;
      tilt = axis.norm() > 1e-3 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()))
                                : Eigen::Quaterniond::Identity();
      key(seconds);
    } else if (pick < 0.83) {  // hold
      key(seconds);
    } else if (pick < 0.90) {  // freeze or unfreeze
      frozen = !frozen;
      script.controls.push_back({at(t), frozen, depth_mm, {}, {}});
      key(seconds);
    } else if (pick < 0.96 || cases.size() == 1) {  // switch method
      const auto m = static_cast<std::size_t>(uniform(rng, 0.0, std::size(kLiveMethods)));
      script.controls.push_back({at(t), frozen, depth_mm, kLiveMethods[m], {}});
      key(seconds);
    } else {  // another case from the list
      const auto offset = 1 + static_cast<std::size_t>(uniform(rng, 0.0, cases.size() - 1.0));
      switch_case((current + offset) % cases.size(), std::nullopt);
    }
  }
  script.keyframes.back().marker = "end";
  return script;
}

}  // namespace ultrasim::kiosk
