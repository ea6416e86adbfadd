#include "ultrasim/kiosk/headless_run.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/drivers/sim_probe/motion_file.hpp"
#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/kiosk/frame_loop.hpp"
#include "ultrasim/kiosk/probe_sources.hpp"
#include "ultrasim/kiosk/run_report.hpp"
#include "ultrasim/kiosk/script.hpp"
#include "ultrasim/kiosk/session.hpp"
#include "ultrasim/kiosk/soak_script.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/render/kms_display.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/render/scene_renderer.hpp"

namespace ultrasim::kiosk {

namespace {

// sweep-press: the probe's sweep and press over the case, then the controls: freeze, press again
// while frozen (the image must hold while the tissue moves), unfreeze at a deeper setting.
Script sweep_press(const config::CaseScan& scan, double depth_mm) {
  const Eigen::Vector3d start(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]);
  const Eigen::Vector3d end(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2]);
  Script script;
  script.keyframes = drivers::sim_probe::sweep_press_script(start, end, scan.press_depth_mm);
  const auto& last = script.keyframes.back();
  const auto at = [&](double seconds_after) {
    return last.time_us + static_cast<hal::TimestampUs>(seconds_after * 1e6);
  };
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d pressed = last.position_mm + 0.5 * scan.press_depth_mm * down;
  script.keyframes.push_back({at(0.5), pressed, last.orientation, ""});
  script.keyframes.push_back({at(0.75), pressed, last.orientation, "frozen"});
  script.keyframes.push_back({at(1.0), last.position_mm, last.orientation, ""});
  script.keyframes.push_back({at(1.5), last.position_mm, last.orientation, "deeper"});
  script.controls = {{at(0.0), true, depth_mm, {}, {}}, {at(1.0), false, 1.5 * depth_mm, {}, {}}};
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
Script compare_methods(const config::CaseScan& scan) {
  const Eigen::Vector3d middle =
      (Eigen::Vector3d(scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]) +
       Eigen::Vector3d(scan.end_mm[0], scan.end_mm[1], scan.end_mm[2])) /
      2;
  const Eigen::Vector3d down = Eigen::Vector3d::UnitZ();
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  const auto at = [](double seconds) { return static_cast<hal::TimestampUs>(seconds * 1e6); };
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

// The screen as the frame loop's renderer.
class DisplayFrameRenderer final : public FrameRenderer {
 public:
  DisplayFrameRenderer(render::Display& display, render::SceneRenderer& renderer)
      : display_(display), renderer_(renderer) {}
  void render(const Session& session, std::int64_t frame_index) override {
    display_.begin_frame();
    render::FrameInput input = session.frame_input(frame_index);
    input.stats = stats;
    renderer_.draw(input);
    display_.end_frame();
  }
  render::StatsView stats;  // the overlay, refreshed by the run before each frame

 private:
  render::Display& display_;
  render::SceneRenderer& renderer_;
};

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
  if (options.script == "sweep-press") return sweep_press(scan, depth_mm);
  if (options.script == "compare-methods") return compare_methods(scan);
  if (options.script == "soak") {
    std::vector<SoakCase> cases;
    for (const auto& t : tissues) cases.push_back({t.settings.scan, t.settings.probe.depth_mm});
    return soak_script(cases, options.soak_seconds, options.soak_seed);
  }
  throw std::invalid_argument("unknown script '" + options.script +
                              "'; available: sweep-press, compare-methods, soak");
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
  Script script = settings.probe.source == hal::ProbeSourceKind::kScripted &&
                          !settings.probe.motion_file.empty()
                      ? Script{drivers::sim_probe::read_motion_file(settings.probe.motion_file), {}}
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
  std::filesystem::create_directories(options.out_dir);  // only once everything could start
  // Restarted on every pick from the case list.
  auto session_owner = std::make_unique<Session>(tissue, settings, clock, jobs);
  Session* session = session_owner.get();

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
  DisplayFrameRenderer frame_renderer(display, renderer);
  FrameLoop loop(*session, frame_renderer, clock, settings.frame);

  std::size_t next_marker = 0;
  std::size_t next_control = 0;
  render::RgbaImage screen;

  const std::int64_t frames_per_second = std::max<std::int64_t>(1, 1'000'000 / budget_us);
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
        report.saved_images += 1;
        const std::string name = "saved-" + std::to_string(report.saved_images) + ".png";
        render::write_png_grey(options.out_dir / name, session->bscan(), session->bscan_width_px(),
                               session->bscan_height_px(), session->image_record());
      } else if (event.case_index) {
        // The old session goes first: a kiosk holds one case's engines at a time.
        config::AppSettings case_settings = settings;
        case_settings.sim.method = event.method.value_or(session->method());
        const TissueCase& next = tissues.at(static_cast<std::size_t>(*event.case_index));
        if (!method_runs_on(next, case_settings.sim.method)) {
          case_settings.sim.method = first_method_for(next);
          report.method_switches_refused += 1;
        }
        session_owner.reset();
        session_owner = std::make_unique<Session>(next, case_settings, clock, jobs);
        session = session_owner.get();
        loop.switch_session(*session);
        BscanControls controls = session->controls();
        controls.depth_mm = event.depth_mm;
        session->set_controls(controls);
        report.case_switches += 1;
      } else if (event.method) {
        if (!method_runs_on(session->tissue(), *event.method)) {
          report.method_switches_refused += 1;
        } else {
          if (*event.method != session->method()) report.method_switches += 1;
          session->switch_method(*event.method);
        }
      } else {
        BscanControls controls = session->controls();
        controls.frozen = event.frozen;
        controls.depth_mm = event.depth_mm;
        session->set_controls(controls);
      }
      ++next_control;
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
    const sched::TickReport tick =
        loop.run_frame(sample, sample ? source_now - sample->timestamp_us : 0);
    auto by_method = std::ranges::find(report.frame_by_method, method_key,
                                       [](const auto& entry) { return entry.first; });
    if (by_method == report.frame_by_method.end()) {
      report.frame_by_method.emplace_back(method_key, sched::FrameTimeStats(budget_us));
      by_method = report.frame_by_method.end() - 1;
    }
    by_method->second.record(tick.duration_us);
    const FrameOutcome& outcome = loop.outcome();
    if (options.resident_memory_kib && frame % frames_per_second == 0) {
      report.memory_kib.emplace_back(frame, options.resident_memory_kib());
    }

    report.frames += 1;
    report.poses_rejected += outcome.pose_rejected;
    report.frames_in_contact += outcome.in_contact;
    report.diverged_frames += outcome.sim.diverged;
    report.probe_held_frames += outcome.probe_held;
    report.cut_short_frames += outcome.sim.cut_short;
    report.recoveries[static_cast<std::size_t>(outcome.sim.recovery)] += 1;
    report.max_inverted_tets = std::max(report.max_inverted_tets, outcome.sim.inverted_tets);
    report.max_contact_force_n = std::max(report.max_contact_force_n, outcome.sim.contact_force_n);
    if (outcome.stitch) {
      StitchSummary& s = report.stitching;
      s.frames += 1;
      s.sub_volumes_stepped += outcome.stitch->sub_volumes_stepped;
      s.sub_volumes_deferred += outcome.stitch->sub_volumes_deferred;
      s.frames_deferring += outcome.stitch->sub_volumes_deferred > 0;
      s.max_gap_mm = std::max(s.max_gap_mm, outcome.stitch->max_gap_mm);
    }

    // A marker is shown by the last frame at or before it: the next frame would be past it.
    while (next_marker < markers.size() && markers[next_marker].first < now + budget_us) {
      Snapshot snap;
      snap.marker = markers[next_marker].second;
      snap.frame = frame;
      snap.contact_force_n = outcome.sim.contact_force_n;
      snap.method = std::string(sim::engine_key(session->method()));
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

  report.frame = loop.scheduler().frame_stats();
  report.probe_to_photon = loop.probe_to_photon();
  report.tasks.assign(loop.scheduler().task_stats().begin(), loop.scheduler().task_stats().end());
  const auto report_path = options.out_dir / "report.json";
  write_report_json(report_path, report);
  return report_path;
}

}  // namespace ultrasim::kiosk
