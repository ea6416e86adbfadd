#include "ultrasim/kiosk/headless_run.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>
#include <variant>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/drivers/sim_probe/motion_file.hpp"
#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/drivers/touch/evdev_pointer.hpp"
#include "ultrasim/kiosk/frame_loop.hpp"
#include "ultrasim/kiosk/probe_sources.hpp"
#include "ultrasim/kiosk/run_report.hpp"
#include "ultrasim/kiosk/script.hpp"
#include "ultrasim/kiosk/scripted_touch.hpp"
#include "ultrasim/kiosk/service_screen.hpp"
#include "ultrasim/kiosk/session.hpp"
#include "ultrasim/kiosk/session_scripts.hpp"
#include "ultrasim/kiosk/settings_dialog.hpp"
#include "ultrasim/kiosk/soak_script.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/render/kms_display.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/render/scene_renderer.hpp"
#include "ultrasim/render/trainer_ui.hpp"

namespace ultrasim::kiosk {

namespace {

// The screen as the frame loop's renderer: the scene, then the trainer's controls over it.
class DisplayFrameRenderer final : public FrameRenderer {
 public:
  DisplayFrameRenderer(render::Display& display, render::SceneRenderer& renderer,
                       render::TrainerUi& ui)
      : display_(display), renderer_(renderer), ui_(ui) {}
  void render(const Session& session, std::int64_t frame_index) override {
    display_.begin_frame();
    render::FrameInput input = session.frame_input(frame_index);
    input.stats = stats;
    input.view = ui_.view_options();
    renderer_.draw(input);
    actions = ui_.frame(input, renderer_.layout(), model, pointer, frame_seconds);
    pointer = {};
    display_.end_frame();
  }
  render::StatsView stats;     // the overlay, refreshed by the run before each frame
  render::TrainerModel model;  // likewise, the controls' state
  std::span<const hal::PointerEvent> pointer;  // this frame's touches
  float frame_seconds = 0.0f;
  render::TrainerActions actions;  // what the trainee asked for in the last frame drawn

 private:
  render::Display& display_;
  render::SceneRenderer& renderer_;
  render::TrainerUi& ui_;
};

// The live methods as the method list shows them.
constexpr std::string_view kMethodNames[] = {"exact FEM", "PCG FEM", "corotational FEM", "MSDS",
                                             "MSDS implicit"};
static_assert(std::size(kMethodNames) == std::size(kLiveMethods));

// Whether two statuses of the probe's source tell the same trouble: equal but for their
// numbers ("no orientation for 12 ms" and "... 29 ms"), so the log gets a line per change, not
// per frame.
bool same_trouble(std::string_view a, std::string_view b) {
  std::size_t i = 0, j = 0;
  while (true) {
    while (i < a.size() && std::isdigit(static_cast<unsigned char>(a[i]))) ++i;
    while (j < b.size() && std::isdigit(static_cast<unsigned char>(b[j]))) ++j;
    if (i == a.size() || j == b.size()) return i == a.size() && j == b.size();
    if (a[i++] != b[j++]) return false;
  }
}

// The display [display] backend names; `name` says which, for the report.
std::unique_ptr<render::Display> make_display(const render::DisplaySettings& settings,
                                              std::string& name) {
  if (settings.backend == render::DisplayBackend::kKms) {
    render::KmsOptions options;
    options.device = settings.kms_device;
    options.output = {settings.kms_connector, settings.kms_mode_width_px,
                      settings.kms_mode_height_px, settings.kms_refresh_hz};
    options.force_legacy = settings.kms_legacy;
    auto kms = std::make_unique<render::KmsDisplay>(options);
    name = "KMS " + kms->connector_name() + " " + std::to_string(kms->width_px()) + "x" +
           std::to_string(kms->height_px()) + "@" + std::to_string(kms->mode().refresh_hz) +
           (kms->atomic() ? " (atomic)" : " (legacy)");
    return kms;
  }
  auto offscreen = std::make_unique<render::OffscreenDisplay>(settings);
  name = offscreen->renderer_name();
  return offscreen;
}

// The kiosk's default for a case: the first live method that runs on it.
sim::EngineKind first_method_for(const TissueCase& tissue) {
  for (const auto method : kLiveMethods) {
    if (method_runs_on(tissue, method)) return method;
  }
  return sim::EngineKind::kMsdsExplicit;
}

Script make_script(const HeadlessRunOptions& options, std::span<const TissueCase> tissues) {
  const config::CaseScan& scan = tissues.front().settings.scan;
  const double depth_mm = tissues.front().settings.probe.depth_mm;
  if (options.script == "sweep-press") return sweep_press_session(scan, depth_mm);
  if (options.script == "compare-methods") return compare_methods_session(scan);
  if (options.script == "trainer") return trainer_session(scan);
  if (options.script == "soak") {
    std::vector<SoakCase> cases;
    for (const auto& t : tissues) cases.push_back({t.settings.scan, t.settings.probe.depth_mm});
    return soak_script(cases, options.soak_seconds, options.soak_seed);
  }
  throw std::invalid_argument("unknown script '" + options.script +
                              "'; available: sweep-press, compare-methods, trainer, soak");
}

}  // namespace

std::filesystem::path run_headless(const HeadlessRunOptions& options, const hal::Clock& clock,
                                   hal::JobSystem& jobs) {
  config::AppSettings settings =
      options.app_config ? config::load_app_settings(*options.app_config) : config::AppSettings{};
  if (options.method) settings.sim.method = *options.method;
  std::vector<TissueCase> tissues;
  tissues.push_back(load_tissue_case(options.case_dir));
  for (const auto& dir : options.more_cases) tissues.push_back(load_tissue_case(dir));
  const TissueCase& tissue = tissues.front();
  // The settings' method where the case can run it, else the first live method it can (a split
  // case runs the stitchable ones); a method asked for on the command line is kept, and refused
  // with a clear error by the session if the case cannot run it.
  if (!options.method && !method_runs_on(tissue, settings.sim.method)) {
    settings.sim.method = first_method_for(tissue);
  }
  Script script =
      settings.probe.source == hal::ProbeSourceKind::kScripted &&
              !settings.probe.motion_file.empty()
          ? Script{drivers::sim_probe::read_motion_file(settings.probe.motion_file), {}, {}}
          : make_script(options, tissues);
  // Virtual time: frame i shows the script at i budgets, however long the machine takes, so
  // the session (and its screenshots) are the same on every run.
  hal::ManualClock script_clock;
  const bool scripted = settings.probe.source == hal::ProbeSourceKind::kScripted;
  const hal::TimestampUs script_duration_us = script.keyframes.back().time_us;
  ProbeSource probe = make_probe_source(settings.probe, script.keyframes, script_clock, clock);
  // The kiosk runs everything in real time: the script and recordings follow the wall clock.
  const bool real_time = probe.real_time || options.kiosk;
  std::vector<std::pair<hal::TimestampUs, std::string>> markers;
  if (options.kiosk) {
    script.controls.clear();  // the trainee's controls, not a script's
  } else if (scripted) {
    for (const auto& k : script.keyframes)
      if (!k.marker.empty()) markers.emplace_back(k.time_us, k.marker);
  } else {
    // Another source moves the probe: the script's controls and moments do not apply. A
    // screenshot each second instead, and at the end.
    script.controls.clear();
    for (int s = 1; s < options.probe_seconds; ++s)
      markers.emplace_back(s * 1'000'000, "probe-" + std::to_string(s) + "s");
    markers.emplace_back(static_cast<hal::TimestampUs>(options.probe_seconds * 1e6), "probe-end");
  }
  const hal::TimestampUs run_duration_us =
      options.kiosk ? (options.kiosk_seconds > 0.0
                           ? static_cast<hal::TimestampUs>(options.kiosk_seconds * 1e6)
                           : std::numeric_limits<hal::TimestampUs>::max() / 4)
      : scripted    ? script_duration_us
                    : static_cast<hal::TimestampUs>(options.probe_seconds * 1e6);

  std::string display_name;
  const std::unique_ptr<render::Display> display_owner =
      make_display(settings.display, display_name);
  render::Display& display = *display_owner;
  render::SceneRenderer renderer(display);
  render::TrainerUi ui(display);
  // The touch screen or mouse the settings name, else whatever the caller gives (a test's).
  std::unique_ptr<hal::PointerSource> pointer_owner;
  hal::PointerSource* pointer = options.pointer;
  if (!settings.display.pointer_device.empty()) {
    pointer_owner = drivers::touch::open_evdev_pointer(settings.display.pointer_device,
                                                       display.width_px(), display.height_px());
    pointer = pointer_owner.get();
  }
  std::filesystem::create_directories(options.out_dir);  // only once everything could start
  // Restarted on every pick from the case list and every applied settings change.
  auto session_owner = std::make_unique<Session>(tissue, settings, clock, jobs);
  Session* session = session_owner.get();
  std::size_t case_index = 0;

  RunReport report;
  report.case_name = tissue.settings.name;
  report.renderer = display_name;
  report.mesh_nodes = tissue.mesh.node_count();
  report.mesh_tets = tissue.mesh.tet_count();
  report.bscan_width_px = session->bscan_width_px();
  report.bscan_height_px = session->bscan_height_px();
  report.method = std::string(sim::engine_key(session->method()));
  report.threads = jobs.thread_count();
  report.realtime = options.realtime;
  for (const auto& s : tissue.structures) report.surface_triangles += s.rest.triangle_count();
  report.slicer = session->slicer_name();
  report.probe_source = probe_source_key(settings.probe.source);
  const std::int64_t budget_us = settings.frame.budget_us;
  DisplayFrameRenderer frame_renderer(display, renderer, ui);
  frame_renderer.frame_seconds = static_cast<float>(budget_us) * 1e-6f;
  FrameLoop loop(*session, frame_renderer, clock, settings.frame);

  // The controls' model: names and settings fields live here, the spans point at them.
  std::vector<std::string_view> case_names;
  for (const auto& t : tissues) case_names.push_back(t.settings.name);
  std::vector<render::SettingField> fields = settings_fields(settings);
  std::vector<float> tgc_db(imaging::kTgcSliders, 0.0f);
  ServiceScreen service;
  render::TrainerModel& model = frame_renderer.model;
  model.case_names = case_names;
  model.method_names = kMethodNames;
  model.settings = fields;
  model.tgc_db = tgc_db;

  const auto save_image = [&] {
    report.saved_images += 1;
    const std::string name = "saved-" + std::to_string(report.saved_images) + ".png";
    render::write_png_grey(options.out_dir / name, session->bscan(), session->bscan_width_px(),
                           session->bscan_height_px(), session->image_record());
  };
  // The old session goes first: a kiosk holds one case's engines at a time.
  const auto restart = [&](std::size_t index, std::optional<sim::EngineKind> method,
                           std::optional<double> depth_mm) {
    config::AppSettings case_settings = settings;
    case_settings.sim.method = method.value_or(session->method());
    const TissueCase& next = tissues.at(index);
    if (!method_runs_on(next, case_settings.sim.method)) {
      case_settings.sim.method = first_method_for(next);
      report.method_switches_refused += 1;
    }
    session_owner.reset();
    session_owner = std::make_unique<Session>(next, case_settings, clock, jobs);
    session = session_owner.get();
    if (options.return_freed_memory) options.return_freed_memory();
    case_index = index;
    loop.switch_session(*session);
    if (depth_mm) {
      BscanControls controls = session->controls();
      controls.depth_mm = *depth_mm;
      session->set_controls(controls);
    }
  };
  const auto switch_method = [&](sim::EngineKind method) {
    if (!method_runs_on(session->tissue(), method)) {
      report.method_switches_refused += 1;
      return;
    }
    if (method != session->method()) report.method_switches += 1;
    session->switch_method(method);
  };
  const auto set_controls = [&](const BscanControls& controls) {
    try {
      session->set_controls(controls);
    } catch (const std::invalid_argument&) {
      report.controls.refused_values += 1;  // a step past the control's range: nothing changes
    }
  };
  // What the trainee asked for on screen in the frame just drawn.
  const auto apply_actions = [&](const render::TrainerActions& a) {
    BscanControls controls = session->controls();
    bool changed = false;
    if (a.toggle_freeze) controls.frozen = !controls.frozen, changed = true;
    if (a.gain_db) controls.gain_db = *a.gain_db, changed = true;
    if (a.depth_mm) controls.depth_mm = *a.depth_mm, changed = true;
    if (a.tgc_slider >= 0 && a.tgc_slider < imaging::kTgcSliders) {
      controls.tgc_db[static_cast<std::size_t>(a.tgc_slider)] = a.tgc_db;
      changed = true;
    }
    if (a.compression_steps != 0) {
      constexpr double kCompressionStepMm = 2.0;
      controls.compression_mm =
          std::clamp(controls.compression_mm + kCompressionStepMm * a.compression_steps, 0.0, 20.0);
      changed = true;
    }
    if (changed) set_controls(controls);
    if (a.save) save_image();
    if (a.method_index >= 0 && a.method_index < static_cast<int>(std::size(kLiveMethods))) {
      switch_method(kLiveMethods[static_cast<std::size_t>(a.method_index)]);
    }
    if (a.case_index >= 0 && static_cast<std::size_t>(a.case_index) < tissues.size()) {
      restart(static_cast<std::size_t>(a.case_index), std::nullopt, std::nullopt);
      report.case_switches += 1;
    }
    if (!a.settings_applied.empty()) {
      auto result = apply_settings_fields(settings, a.settings_applied);
      if (auto* refusal = std::get_if<std::string>(&result)) {
        ui.settings_refused(*refusal);
        report.controls.settings_refused += 1;
        report.controls.last_refusal = *refusal;
      } else {
        const BscanControls kept = session->controls();
        const sim::EngineKind method = session->method();
        settings = std::get<config::AppSettings>(std::move(result));
        fields = settings_fields(settings);
        model.settings = fields;
        // The simulation starts again with the new numbers; the scanner keeps its settings.
        restart(case_index, method, std::nullopt);
        set_controls(kept);
        ui.settings_accepted();
        report.controls.settings_applied += 1;
      }
    }
  };

  std::size_t next_marker = 0;
  std::size_t next_control = 0;
  ScriptedTouch touch(script.ui);
  std::vector<hal::PointerEvent> pointer_events;
  render::RgbaImage screen;

  const std::int64_t frames_per_second = std::max<std::int64_t>(1, 1'000'000 / budget_us);
  RunReport::SecondSample second;  // the second's strongest press and widest seam so far
  if (options.script == "soak") {
    report.memory_baseline_frame =
        static_cast<std::int64_t>(soak_warm_up_s(tissues.size()) * 1e6) / budget_us;
  }

  // One frame past the script's end, so its last moment is shown too.
  const std::int64_t frame_count = run_duration_us / budget_us + 2;
  const hal::TimestampUs real_start_us = clock.now_us();
  hal::TimestampUs last_frame_start_us = -1;
  double measured_fps = 0.0;  // frame starts a second, smoothed
  for (std::int64_t frame = 0; frame < frame_count; ++frame) {
    if (options.stop != nullptr && options.stop->load(std::memory_order_relaxed)) break;
    if (real_time) {
      // A device moves in real time: each frame starts on its budget's boundary.
      const hal::TimestampUs due = real_start_us + frame * budget_us;
      const hal::TimestampUs wait_us = due - clock.now_us();
      if (wait_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(wait_us));
      script_clock.advance_us(clock.now_us() - real_start_us - script_clock.now_us());
    }
    const hal::TimestampUs now = script_clock.now_us();
    while (next_control < script.controls.size() && script.controls[next_control].time_us <= now) {
      const ControlEvent& event = script.controls[next_control];
      if (event.save) {
        save_image();
      } else if (event.case_index) {
        restart(static_cast<std::size_t>(*event.case_index), event.method, event.depth_mm);
        report.case_switches += 1;
      } else if (event.method) {
        switch_method(*event.method);
      } else {
        BscanControls controls = session->controls();
        controls.frozen = event.frozen;
        controls.depth_mm = event.depth_mm;
        set_controls(controls);
      }
      ++next_control;
    }
    // The touches: the script's, placed on the screen as last drawn, and the touch screen's.
    {
      const render::FrameInput shown = session->frame_input(frame);
      const auto touches = touch.advance(frame, now, ui, renderer.layout(), shown.bscan.width_mm,
                                         shown.bscan.depth_mm);
      pointer_events.assign(touches.begin(), touches.end());
      if (pointer != nullptr) {
        const auto touched = pointer->poll();
        pointer_events.insert(pointer_events.end(), touched.begin(), touched.end());
      }
      frame_renderer.pointer = pointer_events;
      const BscanControls& c = session->controls();
      model.gain_db = static_cast<float>(c.gain_db);
      model.depth_mm = static_cast<float>(c.depth_mm);
      model.frozen = c.frozen;
      model.compression_mm = static_cast<float>(c.compression_mm);
      for (std::size_t i = 0; i < tgc_db.size(); ++i) tgc_db[i] = static_cast<float>(c.tgc_db[i]);
      model.case_index = static_cast<int>(case_index);
      model.method_index = static_cast<int>(std::ranges::find(kLiveMethods, session->method()) -
                                            std::begin(kLiveMethods));
    }
    const std::string method_key(sim::engine_key(session->method()));
    // A device's samples carry the monotonic clock's time; the script's and recordings' the
    // virtual clock's.
    const hal::TimestampUs source_now = probe.real_time ? clock.now_us() : now;  // its clock
    const auto sample = probe.pose->latest(source_now);
    const std::string_view probe_status = probe.pose->status_text();
    if (options.log_line && !same_trouble(probe_status, session->probe_status())) {
      char when[32];
      std::snprintf(when, sizeof when, "%.3f s: probe ", static_cast<double>(now) * 1e-6);
      options.log_line(when +
                       (probe_status.empty() ? std::string("ok") : std::string(probe_status)));
    }
    session->set_probe_status(probe_status);
    if (!probe_status.empty()) {
      report.probe_status_frames += 1;
      if (report.probe_last_status != probe_status) report.probe_last_status = probe_status;
    }
    // The overlay: how the kiosk keeps up, as of the frames before this one.
    {
      const hal::TimestampUs frame_start_us = clock.now_us();
      if (last_frame_start_us >= 0 && frame_start_us > last_frame_start_us) {
        const double fps = 1e6 / static_cast<double>(frame_start_us - last_frame_start_us);
        measured_fps = measured_fps > 0.0 ? 0.9 * measured_fps + 0.1 * fps : fps;
      }
      last_frame_start_us = frame_start_us;
      const sched::FrameTimeStats& frames = loop.scheduler().frame_stats();
      render::StatsView& stats = frame_renderer.stats;
      stats.shown = true;
      stats.frames_per_second = static_cast<float>(measured_fps);
      stats.frame_p99_ms = static_cast<float>(frames.percentile_us(99.0)) * 1e-3f;
      stats.budget_use_percent =
          100.0f * static_cast<float>(frames.percentile_us(50.0)) / static_cast<float>(budget_us);
      stats.deadline_misses = frames.deadline_misses();
      stats.probe_to_photon_p99_ms =
          static_cast<float>(loop.probe_to_photon().percentile_us(99.0)) * 1e-3f;
      stats.probe_source = probe.pose->name();
      stats.probe_ok = probe_status.empty();
    }
    if (frame % 30 == 0) {
      service.refresh(display_name, *probe.pose, probe_status, pointer, *session,
                      tissues[case_index].settings.name, loop.scheduler(),
                      options.resident_memory_kib);
      model.service = service.lines;
    }
    const sched::TickReport tick =
        loop.run_frame(sample, sample ? source_now - sample->timestamp_us : 0);
    apply_actions(frame_renderer.actions);
    frame_renderer.actions = {};
    if (ui.calipers().points == 2) report.controls.caliper_mm = ui.calipers().distance_mm();
    auto by_method =
        std::ranges::find(report.frame_by_method, method_key, &RunReport::MethodFrames::method);
    if (by_method == report.frame_by_method.end()) {
      report.frame_by_method.push_back(
          {method_key, sched::FrameTimeStats(budget_us), sched::FrameTimeStats(budget_us)});
      by_method = report.frame_by_method.end() - 1;
    }
    by_method->whole.record(tick.duration_us);
    by_method->render_capped.record(loop.last_frame_render_capped_us());
    const FrameOutcome& outcome = loop.outcome();
    if (frame % frames_per_second == 0) {
      if (options.resident_memory_kib) {
        report.memory_kib.emplace_back(frame, options.resident_memory_kib());
      }
      if (options.heap_in_use_kib) {
        report.heap_in_use_kib.emplace_back(frame, options.heap_in_use_kib());
      }
    }

    report.frames += 1;
    second.max_contact_force_n = std::max(second.max_contact_force_n, outcome.sim.contact_force_n);
    if (outcome.stitch) second.max_gap_mm = std::max(second.max_gap_mm, outcome.stitch->max_gap_mm);
    const std::int64_t capped_us = loop.last_frame_render_capped_us();
    second.late_frames += capped_us > budget_us;
    if (capped_us > second.slowest_frame_us) {
      second.slowest_frame_us = capped_us;
      second.slowest_frame_simulation_us = loop.last_simulation_us();
      second.slowest_frame_method = method_key;
      const FrameLoop::OtherTasksUs others = loop.last_other_tasks_us();
      second.slowest_frame_bscan_us = others.bscan;
      second.slowest_frame_view_us = others.view;
      second.slowest_frame_render_us = others.render_capped;
    }
    if (report.frames % frames_per_second == 0) {
      second.frame = frame;
      report.per_second.push_back(second);
      second = {};
    }
    report.poses_rejected += outcome.pose_rejected;
    report.frames_in_contact += outcome.in_contact;
    report.diverged_frames += outcome.sim.diverged;
    report.probe_held_frames += outcome.probe_held;
    report.cut_short_frames += outcome.sim.cut_short;
    report.recoveries[static_cast<std::size_t>(outcome.sim.recovery)] += 1;
    if (outcome.sim.diverged) report.causes[static_cast<std::size_t>(outcome.sim.cause)] += 1;
    report.recovery_events.record(
        frame, static_cast<double>(now) * 1e-6, tissues[case_index].settings.name, method_key,
        outcome.sim.recovery, outcome.sim.contact_force_n, outcome.sim.cause);
    report.max_inverted_tets = std::max(report.max_inverted_tets, outcome.sim.inverted_tets);
    report.max_contact_force_n = std::max(report.max_contact_force_n, outcome.sim.contact_force_n);
    if (outcome.stitch) {
      StitchSummary& s = report.stitching;
      s.frames += 1;
      s.sub_volumes_stepped += outcome.stitch->sub_volumes_stepped;
      s.sub_volumes_deferred += outcome.stitch->sub_volumes_deferred;
      s.frames_deferring += outcome.stitch->sub_volumes_deferred > 0;
      s.frames_in_fewer_exchanges += outcome.stitch->exchanges_left_out > 0;
      s.updates_held += outcome.stitch->updates_held;
      s.max_gap_mm = std::max(s.max_gap_mm, outcome.stitch->max_gap_mm);
    }

    // A marker is shown by the last frame at or before it: the next frame would be past it.
    while (next_marker < markers.size() && markers[next_marker].first < now + budget_us) {
      Snapshot snap;
      snap.marker = markers[next_marker].second;
      snap.frame = frame;
      snap.contact_force_n = outcome.sim.contact_force_n;
      snap.method = std::string(sim::engine_key(session->method()));
      snap.skin_dent_mm = session->skin_dent_mm();
      const BscanControls& c = session->controls();
      snap.compression_mm = c.compression_mm;
      snap.depth_mm = c.depth_mm;
      snap.gain_db = c.gain_db;
      snap.frozen = c.frozen;
      snap.caliper_mm = ui.calipers().points == 2 ? ui.calipers().distance_mm() : 0.0;
      snap.view_azimuth_offset_deg = ui.view_options().azimuth_offset_deg;
      snap.view_elevation_offset_deg = ui.view_options().elevation_offset_deg;
      snap.view_zoom = ui.view_options().zoom;
      snap.bscan_png = "bscan-" + snap.marker + ".png";
      snap.screen_png = "screen-" + snap.marker + ".png";
      render::write_png_grey(options.out_dir / snap.bscan_png, session->bscan(),
                             session->bscan_width_px(), session->bscan_height_px());
      display.read_pixels_into(screen);
      render::write_png(options.out_dir / snap.screen_png, screen);
      report.snapshots.push_back(snap);
      ++next_marker;
    }
    if (!real_time) script_clock.advance_us(budget_us);
  }
  if (report.frames % frames_per_second != 0) {  // the last, partial second
    second.frame = report.frames - 1;
    report.per_second.push_back(second);
  }

  report.controls.taps = touch.delivered();
  report.controls.taps_missed = touch.missed();
  report.controls.missed = touch.missed_labels();
  report.frame = loop.scheduler().frame_stats();
  report.frame_render_capped = loop.frame_time_render_capped();
  report.probe_to_photon = loop.probe_to_photon();
  report.tasks.assign(loop.scheduler().task_stats().begin(), loop.scheduler().task_stats().end());
  const auto report_path = options.out_dir / "report.json";
  write_report_json(report_path, report);
  return report_path;
}

}  // namespace ultrasim::kiosk
