#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "ultrasim/kiosk/recovery_events.hpp"
#include "ultrasim/sched/frame_time_stats.hpp"
#include "ultrasim/sched/scheduler.hpp"

namespace ultrasim::kiosk {

struct Snapshot {
  std::string marker;
  std::int64_t frame = 0;
  std::string bscan_png;
  std::string screen_png;
  double contact_force_n = 0.0;
  std::string method;  // deformation method shown
  // What the trainee sees measured: the skin's dent under the probe, the compression buttons'
  // press and the calipers' readout (0: not placed).
  double skin_dent_mm = 0.0;
  double compression_mm = 0.0;
  double caliper_mm = 0.0;
  double depth_mm = 0.0;
  double gain_db = 0.0;
  bool frozen = false;
  // How the trainee looks at the 3D view (render::ViewOptions): orbit and zoom.
  double view_azimuth_offset_deg = 0.0;
  double view_elevation_offset_deg = 0.0;
  double view_zoom = 1.0;
};

// What the trainer's controls did (render::TrainerUi): touches, and what they changed.
struct ControlsSummary {
  std::int64_t taps = 0;            // scripted touches delivered
  std::int64_t taps_missed = 0;     // scripted taps on a control that was not on screen
  std::vector<std::string> missed;  // their labels (the first ten)
  std::int64_t settings_applied = 0;
  std::int64_t settings_refused = 0;
  std::string last_refusal;         // the schema's words, as the dialog showed them
  double caliper_mm = 0.0;          // the last readout with both points placed
  std::int64_t refused_values = 0;  // a step past a control's range (nothing changed)
};

// What stitched frames did (frames a stitched method ran).
struct StitchSummary {
  std::int64_t frames = 0;
  std::int64_t sub_volumes_stepped = 0;   // summed over the frames
  std::int64_t sub_volumes_deferred = 0;  // summed: due but left for later (selection or time)
  std::int64_t frames_deferring = 0;      // frames that left any due sub-volume for later
  // Frames that ran fewer seam exchanges than the method's (no time for their least work).
  std::int64_t frames_in_fewer_exchanges = 0;
  // Summed: corotational updates held for want of time (refused frames' too).
  std::int64_t updates_held = 0;
  double max_gap_mm = 0.0;  // largest gap between copies of a shared node
};

// Everything a headless run measured.
struct RunReport {
  std::string case_name;
  std::string renderer;
  int mesh_nodes = 0;
  int mesh_tets = 0;
  int bscan_width_px = 0;
  int bscan_height_px = 0;
  std::string method;  // deformation method at the start (engine_key)
  int threads = 1;
  std::string realtime;  // how the frame threads were set up (HeadlessRunOptions::realtime)
  int surface_triangles = 0;
  std::string slicer;
  std::int64_t frames = 0;
  std::int64_t poses_rejected = 0;
  // The probe's pose source ([probe] source), the frames it had something to say (not fresh:
  // waiting, stale, fault) and the last thing it said.
  std::string probe_source;
  std::int64_t probe_status_frames = 0;
  std::string probe_last_status;
  std::int64_t saved_images = 0;  // the save control's PNGs (saved-N.png)
  ControlsSummary controls;
  // From each accepted pose's measurement to its frame's presentation (FrameLoop).
  sched::FrameTimeStats probe_to_photon;
  std::int64_t frames_in_contact = 0;
  std::int64_t method_switches = 0;
  std::int64_t method_switches_refused = 0;  // methods that cannot run on the case (stitched)
  std::int64_t case_switches = 0;
  std::int64_t diverged_frames = 0;
  std::int64_t probe_held_frames = 0;        // a refused press held where the method last took it
  std::int64_t cut_short_frames = 0;         // the frame's budget stopped the method's work early
  std::array<std::int64_t, 4> recoveries{};  // frames per sim::Recovery value
  // Diverged frames per sim::DivergenceCause value: what the checks found.
  std::array<std::int64_t, sim::kDivergenceCauseCount> causes{};
  RecoveryEvents recovery_events;  // when, on which case and method, how hard pressed
  int max_inverted_tets = 0;
  double max_contact_force_n = 0.0;
  StitchSummary stitching;
  sched::FrameTimeStats frame{0};  // whole frames against the frame budget
  // Frames with the rendering counted at no more than its reserve
  // (FrameLoop::frame_time_render_capped): the schedule's part, whatever the rasteriser's speed.
  sched::FrameTimeStats frame_render_capped{0};
  // Frames by the deformation method that ran them (engine_key), in the order first used: the
  // trainee's choice of method decides most of a frame's time.
  struct MethodFrames {
    std::string method;
    sched::FrameTimeStats whole;
    sched::FrameTimeStats render_capped;
  };
  std::vector<MethodFrames> frame_by_method;
  std::vector<sched::TaskStats> tasks;  // the frame loop's tasks, in the order they run
  std::vector<Snapshot> snapshots;
  // Resident memory, KiB, once a second of the script: (frame, KiB). Growth: the median of the
  // last quarter of the samples taken after `memory_baseline_frame` (a warm-up) less that of the
  // first quarter, so that a cache filling or a case's buffers coming and going do not count
  // and a leak, growing all along, does; 0 with fewer than 4 samples.
  std::vector<std::pair<std::int64_t, std::int64_t>> memory_kib;
  // Alongside, what the program holds allocated (heap_in_use_kib), sampled the same way: resident
  // memory that steps up while this does not is freed memory the allocator kept, not a leak.
  std::vector<std::pair<std::int64_t, std::int64_t>> heap_in_use_kib;
  // Once a second of frames, the strongest press and the widest stitched seam over that second
  // (its last frame): where a run's largest figures came from, and how they grew. And where its
  // late frames came from: how many of the second's frames were over the budget with the
  // rendering at its reserve, and its slowest frame's time (so measured), method and its tasks'
  // times (the rendering at its reserve; what is left of the frame went between them: the
  // scheduler, and the host's other threads), late or not.
  struct SecondSample {
    std::int64_t frame = 0;
    double max_contact_force_n = 0.0;
    double max_gap_mm = 0.0;
    int late_frames = 0;
    std::int64_t slowest_frame_us = 0;
    std::int64_t slowest_frame_simulation_us = 0;
    std::string slowest_frame_method;
    std::int64_t slowest_frame_bscan_us = 0;
    std::int64_t slowest_frame_view_us = 0;
    std::int64_t slowest_frame_render_us = 0;
  };
  std::vector<SecondSample> per_second;
  std::int64_t memory_baseline_frame = 0;
  std::int64_t memory_growth_kib() const { return growth_kib(memory_kib); }
  std::int64_t heap_in_use_growth_kib() const { return growth_kib(heap_in_use_kib); }
  // Growth of resident memory less the heap in use, sample by sample: the code, the renderer's
  // own mappings and what the allocator keeps of freed memory. Freed memory kept, this grows
  // at each case switch (the old case's engines freed, the new one's fewer); handed back, not.
  std::int64_t resident_beyond_heap_growth_kib() const;
  // Growth of one series of (frame, KiB) samples, as above.
  std::int64_t growth_kib(const std::vector<std::pair<std::int64_t, std::int64_t>>& samples) const;
};

// Writes the report as JSON (times in µs). Throws std::runtime_error naming the path on failure.
void write_report_json(const std::filesystem::path& path, const RunReport& report);

}  // namespace ultrasim::kiosk
