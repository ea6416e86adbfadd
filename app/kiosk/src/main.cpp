// ultrasim-kiosk: the composition root. The only place that picks drivers and back ends.

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <iostream>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/drivers/posix/process_memory.hpp"
#include "ultrasim/drivers/posix/realtime.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/kiosk/compression_study.hpp"
#include "ultrasim/kiosk/headless_run.hpp"
#include "ultrasim/sim/engine_factory.hpp"

#ifndef ULTRASIM_DEFAULT_CASE_DIR
#define ULTRASIM_DEFAULT_CASE_DIR "cases/default"
#endif

namespace {

// Set by SIGINT/SIGTERM: the kiosk finishes its frame, restores the display and exits.
std::atomic<bool> g_stop{false};
void request_stop(int) {
  g_stop.store(true);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ultrasim kiosk: interactive ultrasound training with soft-tissue deformation"};
  ultrasim::kiosk::HeadlessRunOptions options;
  options.case_dir = ULTRASIM_DEFAULT_CASE_DIR;
  options.out_dir = "out/run";
  bool headless = false;
  double kiosk_seconds = 0.0;
  std::string config_path;
  int threads = 2;
  app.add_flag("--headless", headless,
               "a test run: the script (or [probe] source) on a virtual clock, PNG screenshots "
               "and a report; without it, the kiosk: [display] and [probe] in real time until "
               "SIGINT/SIGTERM");
  app.add_option("--kiosk-seconds", kiosk_seconds,
                 "the kiosk (no --headless): stop after this many seconds (0: run until a signal)")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--case", options.case_dir, "case folder (holding case.toml)")
      ->capture_default_str();
  app.add_option("--config", config_path, "app settings (TOML); defaults when omitted");
  app.add_option("--also-case", options.more_cases,
                 "more cases for the case list: --script soak picks among --case and these "
                 "(repeatable)");
  app.add_option("--script", options.script,
                 "scripted session for headless runs: sweep-press (default), compare-methods, "
                 "trainer (the on-screen controls by scripted touches), soak")
      ->capture_default_str();
  app.add_option("--out", options.out_dir, "output folder for PNGs and report.json")
      ->capture_default_str();
  app.add_option("--threads", threads, "threads for the frame's parallel work (the kiosk: 2)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--soak-seconds", options.soak_seconds,
                 "length of --script soak's random session, virtual seconds (>= 6)")
      ->capture_default_str();
  app.add_option("--seed", options.soak_seed, "seed of --script soak's random session")
      ->capture_default_str();
  app.add_option("--probe-seconds", options.probe_seconds,
                 "how long a headless run lasts whose [probe] source is not the script (a "
                 "recording, a device, the keyboard), seconds")
      ->check(CLI::Range(0.1, 1e6))
      ->capture_default_str();
  bool realtime = false;
  app.add_flag("--realtime", realtime,
               "frame threads SCHED_FIFO and pinned one per core, memory locked, where the OS "
               "allows (what it refuses is reported, not fatal)");
  std::string study_csv, study_method = "exact";
  int study_frames = 1;
  double study_step_mm = 0.25, study_depth_mm = 15.0;
  app.add_option("--compression-study", study_csv,
                 "press over the case's vein and artery and write force and lumen areas to this "
                 "CSV (headless)");
  app.add_option("--method", study_method,
                 "deformation method: exact, pcg, corotational, msds-explicit, msds-implicit, "
                 "hyperelastic (headless runs: overrides the settings' [sim] method; "
                 "--compression-study: exact unless given)");
  app.add_option("--study-step-mm", study_step_mm, "press step of --compression-study, mm")
      ->check(CLI::Range(0.01, 10.0))
      ->capture_default_str();
  app.add_option("--study-depth-mm", study_depth_mm, "deepest press of --compression-study, mm")
      ->check(CLI::Range(0.1, 100.0))
      ->capture_default_str();
  app.add_option("--frames-per-step", study_frames,
                 "frames simulated at each depth of --compression-study")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (!study_csv.empty()) {
    try {
      const auto method = ultrasim::sim::engine_from_key(study_method);
      if (!method) throw std::invalid_argument("unknown --method '" + study_method + "'");
      const auto settings = config_path.empty() ? ultrasim::config::AppSettings{}
                                                : ultrasim::config::load_app_settings(config_path);
      const auto tissue = ultrasim::kiosk::load_tissue_case(options.case_dir);
      ultrasim::drivers::posix::ThreadPool jobs(threads);
      ultrasim::kiosk::CompressionStudyOptions study_options;
      study_options.method = *method;
      study_options.frames_per_step = study_frames;
      study_options.step_mm = study_step_mm;
      study_options.max_depth_mm = study_depth_mm;
      study_options.on_sample = [](const ultrasim::kiosk::CompressionSample& s) {
        std::cerr << "  depth " << s.depth_mm << " mm: force " << s.force_n << " N, vein "
                  << s.vein_area_mm2 << " mm², artery " << s.artery_area_mm2 << " mm²\n";
      };
      const auto study =
          ultrasim::kiosk::run_compression_study(tissue, settings, study_options, jobs);
      ultrasim::kiosk::write_compression_csv(study_csv, study);
      std::cout << "ultrasim-kiosk: wrote " << study_csv << "; F_v = "
                << (study.vein_collapse_force_n ? std::to_string(*study.vein_collapse_force_n)
                                                : std::string("not reached"))
                << " N; artery at 3 F_v: "
                << (study.artery_fraction_at_3fv
                        ? std::to_string(100.0 * *study.artery_fraction_at_3fv) + " %"
                        : std::string("not reached"))
                << "\n";
      return 0;
    } catch (const std::exception& e) {
      std::cerr << "ultrasim-kiosk: " << e.what() << "\n";
      return 1;
    }
  }

  if (!headless) {
    // The kiosk itself: the configured display and probe, in real time, until a signal.
    options.kiosk = true;
    options.kiosk_seconds = kiosk_seconds;
    options.stop = &g_stop;
    std::signal(SIGINT, request_stop);
    std::signal(SIGTERM, request_stop);
  }
  if (!config_path.empty()) options.app_config = config_path;
  if (app.count("--method") > 0) {
    options.method = ultrasim::sim::engine_from_key(study_method);
    if (!options.method) {
      std::cerr << "ultrasim-kiosk: unknown --method '" << study_method
                << "'; one of exact, pcg, corotational, msds-explicit, msds-implicit, "
                   "hyperelastic\n";
      return 2;
    }
  }
  try {
    namespace posix = ultrasim::drivers::posix;
    const posix::MonotonicClock clock;
    const posix::RealtimeRequest request;
    // The workers first: a thread starts with its creator's CPU mask, so the frame thread pins
    // itself (as frame thread 0) only once they have chosen their own cores.
    posix::ThreadPool jobs(threads, realtime ? &request : nullptr);
    if (realtime) {
      const std::string memory = posix::lock_process_memory(request);
      options.realtime =
          "memory " + (memory.empty() ? std::string("locked") : memory) +
          "; thread 0: " + posix::describe(posix::make_this_thread_realtime(request, 0), request);
    }
    for (std::size_t i = 0; i < jobs.worker_realtime().size(); ++i) {
      options.realtime += "; thread " + std::to_string(i + 1) + ": " +
                          posix::describe(jobs.worker_realtime()[i], request);
    }
    if (realtime) std::cerr << "ultrasim-kiosk: realtime: " << options.realtime << "\n";
    options.resident_memory_kib = posix::resident_memory_kib;
    options.heap_in_use_kib = posix::heap_in_use_kib;
    options.return_freed_memory = posix::return_freed_memory;
    options.log_line = [](const std::string& line) {
      std::cerr << "ultrasim-kiosk: " << line << '\n';
    };
    const auto report = ultrasim::kiosk::run_headless(options, clock, jobs);
    std::cout << "ultrasim-kiosk: wrote " << report.string() << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-kiosk: " << e.what() << "\n";
    return 1;
  }
}
