#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "ultrasim/hal/clock.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/hal/pointer_input.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

struct HeadlessRunOptions {
  std::filesystem::path case_dir;
  // The rest of the case list: script "soak" picks among case_dir and these.
  std::vector<std::filesystem::path> more_cases;
  std::optional<std::filesystem::path> app_config;  // app.toml; defaults when absent
  std::optional<sim::EngineKind> method;            // overrides the settings' [sim] method
  std::filesystem::path out_dir;                    // created if missing
  std::string script = "sweep-press";               // the scripted probe's motion
  // How long a run lasts whose probe is not the script ([probe] source: a recording, a device,
  // the keyboard), seconds; a screenshot is taken each second. Devices run in real time.
  double probe_seconds = 10.0;
  // How the frame threads run (realtime scheduling, pinning, locked memory), as the composition
  // root set them up: copied into report.json.
  std::string realtime = "not requested";
  // script "soak": how long (virtual seconds) and its random session's seed.
  double soak_seconds = 60.0;
  std::uint64_t soak_seed = 1;
  // The process's resident memory in KiB (an OS query the composition root injects), sampled
  // once a second of the script into report.json; unset: not sampled.
  std::function<std::int64_t()> resident_memory_kib;
  // What the program holds allocated, KiB (the allocator's count), sampled with it; unset: not.
  std::function<std::int64_t()> heap_in_use_kib;
  // Hands freed memory back to the system (an OS call the composition root injects), after each
  // case switch: the old case's engines are freed then; unset: left to the allocator.
  std::function<void()> return_freed_memory;
  // The kiosk itself rather than a test run: every source moves in real time, frames are paced
  // by the display (a KMS display's vblank; the budget offscreen), no screenshots are taken, and
  // the run lasts until *stop turns true (a signal) or, when kiosk_seconds > 0, that long.
  bool kiosk = false;
  double kiosk_seconds = 0.0;
  const std::atomic<bool>* stop = nullptr;
  // Where the run says what happens to the probe's source (a line when its trouble starts,
  // changes or clears, with the run's time); unset: nowhere.
  std::function<void(const std::string&)> log_line;
  // The trainer's touch screen or mouse (drivers/evdev), for the kiosk; null: the script's
  // touches only (a test run) or none.
  hal::PointerSource* pointer = nullptr;
};

// Runs the kiosk without a screen: a scripted session (the probe's motion and the scanner's
// controls: freeze, depth), or the probe source the settings' [probe] names for
// options.probe_seconds (screenshots each second; a device in real time, paced to the frame
// budget, a recording on the virtual clock), plays through the case on a fixed virtual
// frame clock (one frame per frame budget, so the probe's motion is deterministic); every frame
// runs the frame loop (FrameLoop: simulated, sliced and rendered offscreen as time allows), and at
// each of the script's markers the B-scan and the whole screen are written as PNGs. Writes
// report.json (frames, frame-time percentiles, deadline misses, per-task stats of the frame
// scheduler, contact force) into out_dir. `clock` measures how long work took; `jobs` runs the
// frame's parallel work. Throws on bad input (naming the file); returns the report's path.
std::filesystem::path run_headless(const HeadlessRunOptions& options, const hal::Clock& clock,
                                   hal::JobSystem& jobs);

}  // namespace ultrasim::kiosk
