#pragma once

// The trainer's controls on the kiosk screen, through Dear ImGui's GLES 3 backend: touch and
// mouse (hal::PointerEvent) in, the trainee's requests (TrainerActions) out. Render owns only
// what is interaction itself (calipers, the 3D view's orbit and zoom, which dialog is open);
// everything the controls change lives in the app, which shows it back through TrainerModel.

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "ultrasim/hal/pointer_input.hpp"
#include "ultrasim/render/display.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/render/scene_layout.hpp"

namespace ultrasim::render {

// One number of the settings dialog: `table`.`key` as in app.toml, so that the app can check
// the edit against the config schema.
struct SettingField {
  std::string_view tab;    // "FEM", "MSDS", "SIMULATION": the dialog's page
  std::string_view table;  // app.toml table, e.g. "msds"
  std::string_view key;    // key in that table, e.g. "damping_per_stiffness_s"
  double value = 0.0;      // in force now
  double step = 0.0;       // the -/+ buttons' step (0: none)
  bool integer = false;    // shown and edited without decimals
};

// One line of the service screen: a name and what it reads, red where it is not well.
struct ServiceLine {
  std::string_view label;
  std::string_view value;
  bool ok = true;
};

// What the controls show this frame: the state the app holds.
struct TrainerModel {
  float gain_db = 0.0f;
  float depth_mm = 40.0f;
  std::span<const float> tgc_db;  // one per slider, shallow first
  bool frozen = false;
  float compression_mm = 0.0f;  // the compression buttons' press along the beam
  std::span<const std::string_view> case_names;
  int case_index = 0;
  std::span<const std::string_view> method_names;
  int method_index = 0;
  std::span<const SettingField> settings;  // the settings dialog's fields
  std::span<const ServiceLine> service;    // the service screen's lines
};

// What the trainee asked for this frame. Values are what the control now shows; the app
// decides (a refused value simply stays as the model shows it).
struct TrainerActions {
  static constexpr int kNoChange = -1;
  std::optional<float> gain_db;
  std::optional<float> depth_mm;
  int tgc_slider = kNoChange;  // which slider moved, to tgc_db
  float tgc_db = 0.0f;
  bool toggle_freeze = false;
  bool save = false;
  int compression_steps = 0;  // +1 press harder, -1 ease off
  int case_index = kNoChange;
  int method_index = kNoChange;
  // The settings dialog's Apply: every field's edited value, in TrainerModel::settings order,
  // valid until the next frame(). Answer with settings_refused() or settings_accepted().
  std::span<const double> settings_applied;
};

// The calipers on the B-scan, in image millimetres (lateral from the left edge, depth from the
// probe face). A tap places the first point, the next the second, the third starts again.
struct Calipers {
  int points = 0;  // 0, 1 or 2 placed
  std::array<std::array<float, 2>, 2> mm{};
  float distance_mm() const;  // 0 until both are placed
};

// The trainer's controls for one Display. Render thread only; create after the Display and
// destroy before it. One ImGui context per TrainerUi.
class TrainerUi {
 public:
  // Builds the font atlas for the screen's ui_scale and the backend's GL objects. Allocates.
  explicit TrainerUi(Display& display);
  ~TrainerUi();
  TrainerUi(const TrainerUi&) = delete;
  TrainerUi& operator=(const TrainerUi&) = delete;

  // Takes the pointer's events (at most one button change a frame is applied, the rest wait for
  // the next frames, so a tap that arrives within one frame still presses and releases), lays
  // out and draws the controls over the frame SceneRenderer drew with `layout` (call between
  // its draw() and Display::end_frame()), and returns what the trainee asked for.
  // `frame_seconds`: time since the last frame, for ImGui's timers (0: 1/60 s).
  TrainerActions frame(const FrameInput& input, const ScreenLayout& layout,
                       const TrainerModel& model, std::span<const hal::PointerEvent> events,
                       float frame_seconds = 0.0f);

  // The settings dialog's answer to an Apply: the error (naming the field) shown in it, or the
  // dialog closed.
  void settings_refused(std::string_view message);
  void settings_accepted();

  // How the 3D view is to be drawn: the trainee's orbit, zoom and what is shown. Put into the
  // next FrameInput::view.
  const ViewOptions& view_options() const { return view_; }
  const Calipers& calipers() const { return calipers_; }

  // Where the control labelled `label` was on screen in the last frame ("FREEZE", "GAIN +",
  // a case or method name when its list is open), for scripted input; nullopt if it was not
  // drawn.
  std::optional<PixelRect> widget_rect(std::string_view label) const;

  // Whether the pointer is over a control (so a drag there does not orbit the view).
  bool pointer_over_controls() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ViewOptions view_;
  Calipers calipers_;
};

}  // namespace ultrasim::render
