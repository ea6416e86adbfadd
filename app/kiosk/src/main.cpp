// ultrasim-kiosk: the composition root. The only place that picks drivers and back ends.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <iostream>

#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/kiosk/headless_run.hpp"

#ifndef ULTRASIM_DEFAULT_CASE_DIR
#define ULTRASIM_DEFAULT_CASE_DIR "cases/default"
#endif

int main(int argc, char** argv) {
  CLI::App app{"ultrasim kiosk: interactive ultrasound training with soft-tissue deformation"};
  ultrasim::kiosk::HeadlessRunOptions options;
  options.case_dir = ULTRASIM_DEFAULT_CASE_DIR;
  options.out_dir = "out/run";
  bool headless = false;
  std::string config_path;
  int threads = 2;
  app.add_flag("--headless", headless,
               "run without a display: a scripted probe, PNG screenshots and a report");
  app.add_option("--case", options.case_dir, "case folder (holding case.toml)")
      ->capture_default_str();
  app.add_option("--config", config_path, "app settings (TOML); defaults when omitted");
  app.add_option("--script", options.script, "scripted probe motion for headless runs")
      ->capture_default_str();
  app.add_option("--out", options.out_dir, "output folder for PNGs and report.json")
      ->capture_default_str();
  app.add_option("--threads", threads, "threads for the frame's parallel work (the kiosk: 2)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (!headless) {
    std::cerr << "ultrasim-kiosk: only --headless is available yet (the DRM/KMS display back end "
                 "comes with the kiosk issue)\n";
    return 2;
  }
  if (!config_path.empty()) options.app_config = config_path;
  try {
    const ultrasim::drivers::posix::MonotonicClock clock;
    ultrasim::drivers::posix::ThreadPool jobs(threads);
    const auto report = ultrasim::kiosk::run_headless(options, clock, jobs);
    std::cout << "ultrasim-kiosk: wrote " << report.string() << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-kiosk: " << e.what() << "\n";
    return 1;
  }
}
