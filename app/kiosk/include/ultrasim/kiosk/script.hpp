#pragma once

// A scripted session for headless runs: the probe's keyframed motion and the trainee's control
// changes along it.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

// A change of the scanner's controls at a moment of a script, as a trainee's button press: the
// freeze and depth controls, or (when `method` is set) the live switch of deformation method, or
// (when `case_index` is set) a pick from the case list: the session restarts on that case, with
// `method` if given; or (when `save` is set) the save button.
struct ControlEvent {
  hal::TimestampUs time_us = 0;
  bool frozen = false;
  double depth_mm = 0.0;
  std::optional<sim::EngineKind> method;
  std::optional<int> case_index;
  // The trainer's "save": the B-scan written as a PNG with its record (Session::image_record);
  // nothing else changes.
  bool save = false;
};

// A trainee's touch on the screen at a moment of a script, through the real controls
// (render::TrainerUi): a tap on a control by its label, a tap on the B-scan at a point given in
// image millimetres, a drag across the 3D view or a turn of the wheel over it.
struct UiEvent {
  enum class Kind : std::uint8_t { kTap, kTapImage, kDragView, kWheelView };
  hal::TimestampUs time_us = 0;
  Kind kind = Kind::kTap;
  std::string widget;               // kTap: the control's label ("FREEZE", "PRESS +")
  std::array<float, 2> image_mm{};  // kTapImage: lateral from the image's left edge, depth
  std::array<float, 2> drag_px{};   // kDragView: from the view's centre, screen pixels
  float wheel_notches = 0.0f;       // kWheelView
};

struct Script {
  std::vector<drivers::sim_probe::Keyframe> keyframes;
  std::vector<ControlEvent> controls;
  std::vector<UiEvent> ui;  // in time order
};

// The methods a trainee can switch between live, the kiosk's default first (the hyperelastic
// reference takes seconds a frame).
inline constexpr sim::EngineKind kLiveMethods[] = {
    sim::EngineKind::kExactFem, sim::EngineKind::kPcgFem, sim::EngineKind::kCorotationalFem,
    sim::EngineKind::kMsdsExplicit, sim::EngineKind::kMsdsImplicit};

}  // namespace ultrasim::kiosk
