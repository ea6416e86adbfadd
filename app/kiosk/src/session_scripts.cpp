#include "ultrasim/kiosk/session_scripts.hpp"

#include <algorithm>
#include <string>
#include <utility>

#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/sim/engine_factory.hpp"

namespace ultrasim::kiosk {
namespace {

// The middle of the case's scan line, where the vessels lie.
Eigen::Vector3d scan_middle_mm(const config::CaseScan& scan) {
  return (Eigen::Vector3d(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]) +
          Eigen::Vector3d(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2])) /
         2;
}

// A moment of a script, seconds from its start.
hal::TimestampUs at(double seconds) {
  return static_cast<hal::TimestampUs>(seconds * 1e6);
}

}  // namespace

// sweep-press: the probe's sweep and press over the case, then the controls: freeze, press again
// while frozen (the image must hold while the tissue moves), unfreeze at a deeper setting.
Script sweep_press_session(const config::CaseScan& scan, double depth_mm) {
  const Eigen::Vector3d start(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]);
  const Eigen::Vector3d end(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2]);
  Script script;
  script.keyframes = drivers::sim_probe::sweep_press_script(start, end, scan.press_depth_mm);
  const auto& last = script.keyframes.back();
  const auto after_sweep = [&](double seconds) { return last.time_us + at(seconds); };
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d pressed = last.position_mm + 0.5 * scan.press_depth_mm * down;
  script.keyframes.push_back({after_sweep(0.5), pressed, last.orientation, ""});
  script.keyframes.push_back({after_sweep(0.75), pressed, last.orientation, "frozen"});
  script.keyframes.push_back({after_sweep(1.0), last.position_mm, last.orientation, ""});
  script.keyframes.push_back({after_sweep(1.5), last.position_mm, last.orientation, "deeper"});
  script.controls = {{after_sweep(0.0), true, depth_mm, {}, {}},
                     {after_sweep(1.0), false, 1.5 * depth_mm, {}, {}}};
  // The trainee saves the image at the press (the keyframe marked "pressed").
  for (const auto& k : script.keyframes) {
    if (k.marker == "pressed") {
      ControlEvent save;
      save.time_us = k.time_us;
      save.save = true;
      script.controls.push_back(save);
    }
  }
  std::stable_sort(
      script.controls.begin(), script.controls.end(),
      [](const ControlEvent& a, const ControlEvent& b) { return a.time_us < b.time_us; });
  return script;
}

// compare-methods: the probe presses in the middle of the sweep and holds while the trainee
// switches through every deformation method live; a screenshot per method once it has settled.
Script compare_methods_session(const config::CaseScan& scan) {
  const Eigen::Vector3d middle = scan_middle_mm(scan);
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  Script script;
  script.keyframes = {{at(0.0), middle - 5.0 * down, level, ""},
                      {at(0.5), middle, level, ""},
                      {at(1.5), middle + scan.press_depth_mm * down, level, ""}};
  double t = 1.5;
  for (const auto method : kLiveMethods) {
    script.controls.push_back({at(t), false, 0.0, method, {}});
    t += 1.0;
    script.keyframes.push_back(
        {at(t), middle + scan.press_depth_mm * down, level, std::string(sim::engine_key(method))});
  }
  script.keyframes.push_back({at(t + 0.75), middle - 5.0 * down, level, "lifted"});
  return script;
}

// trainer: the probe rests over the vessels while the trainee works the controls on screen, by
// touch alone: presses with the compression buttons, freezes, measures with the calipers,
// saves, turns gain and depth up, eases off, switches method, orbits the view and cuts the skin
// away, opens the settings (one step of the MSDS, applied) and the service screen.
Script trainer_session(const config::CaseScan& scan) {
  const Eigen::Vector3d middle = scan_middle_mm(scan);
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  Script script;
  script.keyframes = {
      {at(0.0), middle - 5.0 * down, level, ""}, {at(0.5), middle, level, ""},
      {at(1.0), middle, level, "rest"},          {at(2.6), middle, level, "pressed"},
      {at(3.7), middle, level, "measured"},      {at(6.0), middle, level, "released"},
      {at(7.6), middle, level, "orbited"},       {at(9.3), middle, level, "settings"},
      {at(10.0), middle, level, "service"},      {at(10.4), middle, level, ""}};
  const auto tap = [&](double seconds, std::string widget) {
    UiEvent e;
    e.time_us = at(seconds);
    e.widget = std::move(widget);
    script.ui.push_back(e);
  };
  // Four presses of 2 mm: 8 mm, the sweep-press script's depth.
  for (double t : {1.2, 1.4, 1.6, 1.8}) tap(t, "PRESS +");
  tap(2.8, "FREEZE");
  tap(3.0, "CALIPER");
  // 10 mm from the image's left edge, 10 and 30 mm deep: 20 mm apart.
  for (const auto& [t, depth] : {std::pair{3.2, 10.0f}, std::pair{3.4, 30.0f}}) {
    UiEvent e;
    e.time_us = at(t);
    e.kind = UiEvent::Kind::kTapImage;
    e.image_mm = {10.0f, depth};
    script.ui.push_back(e);
  }
  tap(3.8, "SAVE");
  tap(4.0, "FREEZE");
  tap(4.2, "GAIN +");
  tap(4.4, "DEPTH +");
  for (double t : {4.6, 4.8, 5.0, 5.2}) tap(t, "PRESS -");
  tap(6.2, "METHOD");
  tap(6.5, "MSDS");
  UiEvent drag;
  drag.time_us = at(6.8);
  drag.kind = UiEvent::Kind::kDragView;
  drag.drag_px = {-120.0f, 40.0f};
  script.ui.push_back(drag);
  tap(7.2, "SKIN");
  tap(7.8, "SETTINGS");
  tap(8.0, "TAB MSDS");
  tap(8.2, "msds.steps_per_frame +");
  tap(8.5, "APPLY");
  // A time step stepped below zero: the schema refuses it and the dialog says why.
  tap(8.7, "SETTINGS");
  tap(8.8, "TAB MSDS");
  for (double t : {8.9, 8.95, 9.0, 9.05, 9.1, 9.15}) tap(t, "msds.time_step_s -");
  tap(9.2, "APPLY");
  tap(9.5, "CLOSE##SETTINGS CLOSE");
  tap(9.7, "SERVICE");
  return script;
}

}  // namespace ultrasim::kiosk
