#include "ultrasim/kiosk/run_report.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace ultrasim::kiosk {

namespace {

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) continue;  // no control characters in names
    out += c;
  }
  return out + "\"";
}

void write_stats(std::ostream& out, const sched::FrameTimeStats& s) {
  out << "{\"count\": " << s.count() << ", \"min_us\": " << s.min_us()
      << ", \"mean_us\": " << static_cast<std::int64_t>(s.mean_us())
      << ", \"p50_us\": " << s.percentile_us(50) << ", \"p90_us\": " << s.percentile_us(90)
      << ", \"p99_us\": " << s.percentile_us(99) << ", \"max_us\": " << s.max_us()
      << ", \"budget_us\": " << s.budget_us() << ", \"deadline_misses\": " << s.deadline_misses()
      << "}";
}

}  // namespace

std::int64_t RunReport::growth_kib(
    const std::vector<std::pair<std::int64_t, std::int64_t>>& samples) const {
  std::vector<std::int64_t> after;
  for (const auto& [sample_frame, kib] : samples) {
    if (sample_frame >= memory_baseline_frame) after.push_back(kib);
  }
  const std::size_t quarter = after.size() / 4;
  if (quarter == 0) return 0;
  const auto median = [](std::vector<std::int64_t> v) {
    std::ranges::nth_element(v, v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2));
    return v[v.size() / 2];
  };
  return median({after.end() - static_cast<std::ptrdiff_t>(quarter), after.end()}) -
         median({after.begin(), after.begin() + static_cast<std::ptrdiff_t>(quarter)});
}

std::int64_t RunReport::resident_beyond_heap_growth_kib() const {
  std::vector<std::pair<std::int64_t, std::int64_t>> beyond;
  for (std::size_t i = 0; i < std::min(memory_kib.size(), heap_in_use_kib.size()); ++i) {
    if (memory_kib[i].first != heap_in_use_kib[i].first) break;  // not sampled together
    beyond.emplace_back(memory_kib[i].first, memory_kib[i].second - heap_in_use_kib[i].second);
  }
  return growth_kib(beyond);
}

void write_report_json(const std::filesystem::path& path, const RunReport& r) {
  std::ostringstream out;
  out << "{\n"
      << "  \"case\": " << quoted(r.case_name) << ",\n"
      << "  \"renderer\": " << quoted(r.renderer) << ",\n"
      << "  \"mesh\": {\"nodes\": " << r.mesh_nodes << ", \"tets\": " << r.mesh_tets << "},\n"
      << "  \"bscan\": {\"width_px\": " << r.bscan_width_px
      << ", \"height_px\": " << r.bscan_height_px << ", \"slicer\": " << quoted(r.slicer) << "},\n"
      << "  \"threads\": " << r.threads << ",\n"
      << "  \"realtime\": " << quoted(r.realtime) << ",\n"
      << "  \"surface_triangles\": " << r.surface_triangles << ",\n"
      << "  \"sim\": {\"method\": " << quoted(r.method)
      << ", \"method_switches\": " << r.method_switches
      << ", \"method_switches_refused\": " << r.method_switches_refused
      << ", \"case_switches\": " << r.case_switches
      << ", \"max_contact_force_n\": " << r.max_contact_force_n
      << ", \"diverged_frames\": " << r.diverged_frames
      << ", \"probe_held_frames\": " << r.probe_held_frames
      << ", \"cut_short_frames\": " << r.cut_short_frames << ", \"substepped\": " << r.recoveries[1]
      << ", \"reset\": " << r.recoveries[2] << ", \"kept_last_good\": " << r.recoveries[3]
      << ", \"max_inverted_tets\": " << r.max_inverted_tets << ", \"diverged_by_cause\": {";
  for (int c = 1; c < sim::kDivergenceCauseCount; ++c) {
    out << (c > 1 ? ", " : "")
        << quoted(std::string(sim::cause_key(static_cast<sim::DivergenceCause>(c)))) << ": "
        << r.causes[static_cast<std::size_t>(c)];
  }
  out << "}},\n"
      << "  \"recovery_events\": {\"dropped\": " << r.recovery_events.dropped()
      << ", \"events\": [";
  const auto& events = r.recovery_events.events();
  for (std::size_t i = 0; i < events.size(); ++i) {
    const RecoveryEvent& e = events[i];
    out << (i ? ",\n" : "\n") << "    {\"kind\": " << quoted(std::string(sim::recovery_key(e.kind)))
        << ", \"cause\": " << quoted(std::string(sim::cause_key(e.cause)))
        << ", \"first_frame\": " << e.first_frame << ", \"length_frames\": " << e.frames
        << ", \"time_s\": " << e.time_s << ", \"case\": " << quoted(e.case_name)
        << ", \"method\": " << quoted(e.method)
        << ", \"max_contact_force_n\": " << e.max_contact_force_n << "}";
  }
  out << (events.empty() ? "" : "\n  ") << "]},\n"
      << "  \"stitching\": {\"stitched_frames\": " << r.stitching.frames
      << ", \"sub_volumes_stepped\": " << r.stitching.sub_volumes_stepped
      << ", \"sub_volumes_deferred\": " << r.stitching.sub_volumes_deferred
      << ", \"frames_deferring\": " << r.stitching.frames_deferring
      << ", \"frames_in_fewer_exchanges\": " << r.stitching.frames_in_fewer_exchanges
      << ", \"corotational_updates_held\": " << r.stitching.updates_held
      << ", \"max_gap_mm\": " << r.stitching.max_gap_mm << "},\n"
      << "  \"frames\": " << r.frames << ",\n"
      << "  \"frames_in_contact\": " << r.frames_in_contact << ",\n"
      << "  \"poses_rejected\": " << r.poses_rejected << ",\n"
      << "  \"probe\": {\"source\": " << quoted(r.probe_source)
      << ", \"status_frames\": " << r.probe_status_frames
      << ", \"last_status\": " << quoted(r.probe_last_status) << "},\n"
      << "  \"saved_images\": " << r.saved_images << ",\n"
      << "  \"controls\": {\"taps\": " << r.controls.taps
      << ", \"taps_missed\": " << r.controls.taps_missed << ", \"missed\": [";
  for (std::size_t i = 0; i < r.controls.missed.size(); ++i) {
    out << (i ? ", " : "") << quoted(r.controls.missed[i]);
  }
  out << "]"
      << ", \"settings_applied\": " << r.controls.settings_applied
      << ", \"settings_refused\": " << r.controls.settings_refused
      << ", \"last_refusal\": " << quoted(r.controls.last_refusal)
      << ", \"refused_values\": " << r.controls.refused_values
      << ", \"caliper_mm\": " << r.controls.caliper_mm << "},\n"
      << "  \"probe_to_photon\": ";
  write_stats(out, r.probe_to_photon);
  out << ",\n  \"frame_time\": ";
  write_stats(out, r.frame);
  out << ",\n  \"frame_time_render_capped\": ";
  write_stats(out, r.frame_render_capped);
  const auto write_by_method = [&](const char* key,
                                   sched::FrameTimeStats RunReport::MethodFrames::*frames) {
    out << ",\n  \"" << key << "\": {";
    for (std::size_t i = 0; i < r.frame_by_method.size(); ++i) {
      out << (i ? ",\n    " : "\n    ") << quoted(r.frame_by_method[i].method) << ": ";
      write_stats(out, r.frame_by_method[i].*frames);
    }
    out << "\n  }";
  };
  write_by_method("frame_time_by_method", &RunReport::MethodFrames::whole);
  write_by_method("frame_time_by_method_render_capped", &RunReport::MethodFrames::render_capped);
  // Per task: its run times against its own budget, and what the scheduler did with it.
  out << ",\n  \"tasks\": {";
  for (std::size_t i = 0; i < r.tasks.size(); ++i) {
    const sched::TaskStats& t = r.tasks[i];
    out << (i ? ",\n    " : "\n    ") << quoted(std::string(t.name)) << ": {\"runs\": " << t.runs
        << ", \"slips\": " << t.slips << ", \"overruns\": " << t.overruns
        << ", \"forced_runs\": " << t.forced_runs << ", \"time\": ";
    write_stats(out, t.time);
    out << "}";
  }
  out << "\n  },\n  \"snapshots\": [";
  for (std::size_t i = 0; i < r.snapshots.size(); ++i) {
    const Snapshot& s = r.snapshots[i];
    out << (i ? ",\n" : "\n") << "    {\"marker\": " << quoted(s.marker)
        << ", \"frame\": " << s.frame << ", \"bscan\": " << quoted(s.bscan_png)
        << ", \"screen\": " << quoted(s.screen_png) << ", \"method\": " << quoted(s.method)
        << ", \"contact_force_n\": " << s.contact_force_n
        << ", \"skin_dent_mm\": " << s.skin_dent_mm << ", \"compression_mm\": " << s.compression_mm
        << ", \"caliper_mm\": " << s.caliper_mm << ", \"depth_mm\": " << s.depth_mm
        << ", \"gain_db\": " << s.gain_db << ", \"frozen\": " << (s.frozen ? "true" : "false")
        << ", \"view_azimuth_offset_deg\": " << s.view_azimuth_offset_deg
        << ", \"view_elevation_offset_deg\": " << s.view_elevation_offset_deg
        << ", \"view_zoom\": " << s.view_zoom << "}";
  }
  const auto samples = [&out](const std::vector<std::pair<std::int64_t, std::int64_t>>& kib) {
    for (std::size_t i = 0; i < kib.size(); ++i) {
      out << (i ? ", " : "") << "[" << kib[i].first << ", " << kib[i].second << "]";
    }
  };
  out << "\n  ],\n  \"memory\": {\"baseline_frame\": " << r.memory_baseline_frame
      << ", \"growth_kib\": " << r.memory_growth_kib() << ", \"samples_kib\": [";
  samples(r.memory_kib);
  out << "], \"heap_in_use_growth_kib\": " << r.heap_in_use_growth_kib()
      << ", \"heap_in_use_samples_kib\": [";
  samples(r.heap_in_use_kib);
  out << "], \"resident_beyond_heap_growth_kib\": " << r.resident_beyond_heap_growth_kib()
      << "},\n  \"per_second\": [";
  for (std::size_t i = 0; i < r.per_second.size(); ++i) {
    const RunReport::SecondSample& s = r.per_second[i];
    out << (i ? ", " : "") << "{\"frame\": " << s.frame
        << ", \"max_contact_force_n\": " << s.max_contact_force_n
        << ", \"max_gap_mm\": " << s.max_gap_mm << ", \"late_frames\": " << s.late_frames
        << ", \"slowest_frame_us\": " << s.slowest_frame_us
        << ", \"slowest_frame_simulation_us\": " << s.slowest_frame_simulation_us
        << ", \"slowest_frame_method\": \"" << s.slowest_frame_method
        << "\", \"slowest_frame_bscan_us\": " << s.slowest_frame_bscan_us
        << ", \"slowest_frame_view_us\": " << s.slowest_frame_view_us
        << ", \"slowest_frame_render_us\": " << s.slowest_frame_render_us << "}";
  }
  out << "]\n}\n";

  std::ofstream file(path);
  file << out.str();
  if (!file) throw std::runtime_error(path.string() + ": cannot write the report");
}

}  // namespace ultrasim::kiosk
