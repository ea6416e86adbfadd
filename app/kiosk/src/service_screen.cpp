#include "ultrasim/kiosk/service_screen.hpp"

#include <cstdio>

#include "ultrasim/kiosk/frame_loop.hpp"

namespace ultrasim::kiosk {

void ServiceScreen::refresh(std::string_view display, hal::PoseSource& probe,
                            std::string_view probe_status, const hal::PointerSource* pointer,
                            const Session& session, std::string_view case_name,
                            const sched::Scheduler& scheduler,
                            const std::function<std::int64_t()>& resident_memory_kib) {
  static constexpr std::string_view kLabels[] = {
      "DISPLAY",      "PROBE SOURCE",    "PROBE STATUS",    "PROBE AT (MM)",   "CASE",
      "METHOD",       "FRAME P50 / P99", "DEADLINE MISSES", "SKIPPED B-SCANS", "MEMORY",
      "TOUCH / MOUSE"};
  values.assign(std::size(kLabels), std::string());
  static_assert(std::size(kLabels) == 11, "one value per label below");
  char text[96];
  values[0] = display;
  values[1] = probe.name();
  values[2] = probe_status.empty() ? std::string("ok") : std::string(probe_status);
  const render::FrameInput shown = session.frame_input(0);
  const auto& m = shown.probe.probe_to_patient;
  std::snprintf(text, sizeof text, "%.1f  %.1f  %.1f", static_cast<double>(m[12]),
                static_cast<double>(m[13]), static_cast<double>(m[14]));
  values[3] = text;
  values[4] = case_name;
  values[5] = session.method_name();
  const sched::FrameTimeStats& frames = scheduler.frame_stats();
  std::snprintf(text, sizeof text, "%.1f / %.1f MS",
                static_cast<double>(frames.percentile_us(50.0)) * 1e-3,
                static_cast<double>(frames.percentile_us(99.0)) * 1e-3);
  values[6] = text;
  values[7] = std::to_string(frames.deadline_misses());
  std::int64_t bscan_slips = 0;
  for (const auto& t : scheduler.task_stats()) {
    if (std::string_view(t.name) == FrameLoop::kBscan) bscan_slips = t.slips;
  }
  values[8] = std::to_string(bscan_slips);
  values[9] = resident_memory_kib ? std::to_string(resident_memory_kib() / 1024) + " MIB"
                                  : std::string("-");
  values[10] = pointer == nullptr               ? std::string("none")
               : pointer->status_text().empty() ? std::string(pointer->name()) + ": ok"
                                                : std::string(pointer->status_text());
  lines.clear();
  for (std::size_t i = 0; i < values.size(); ++i) lines.push_back({kLabels[i], values[i], true});
  lines[2].ok = probe_status.empty();
  lines[7].ok = frames.deadline_misses() == 0;
  lines[10].ok = pointer == nullptr || pointer->status_text().empty();
}

}  // namespace ultrasim::kiosk
