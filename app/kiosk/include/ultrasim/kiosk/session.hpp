#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/hal/pose_sample.hpp"
#include "ultrasim/imaging/bscan.hpp"
#include "ultrasim/imaging/display_mapping.hpp"
#include "ultrasim/imaging/fast_slicer.hpp"
#include "ultrasim/imaging/published_slicer.hpp"
#include "ultrasim/kiosk/deformable_skin.hpp"
#include "ultrasim/kiosk/refused_press.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/sched/piece_budget.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::kiosk {

// What one frame did, for the stats report.
struct FrameOutcome {
  bool pose_rejected = false;  // the sample was missing, unhealthy or non-finite: last good kept
  bool in_contact = false;     // the probe touches the tissue, so there is an image
  sim::EngineStepStats sim;
  std::optional<sim::StitchStepStats> stitch;  // when the method runs stitched
  // The method refused the probe's pose since it last took it: the tissue was pressed where it
  // last took the probe, backed off or part of the way back to the probe (RefusedPress).
  bool probe_held = false;
};

// The scanner's controls a trainee can change while scanning.
struct BscanControls {
  double gain_db = 0.0;                                        // [-40, 40]
  std::array<double, imaging::kTgcSliders> tgc_db{};           // each [-30, 30]
  double dynamic_range_db = imaging::kRecordedDynamicRangeDb;  // [10, 100]
  double depth_mm = 40.0;                                      // [10, 300]
  bool frozen = false;  // image held; the tissue still follows the probe
  // The compression buttons: the probe pressed this far along its beam beyond where the tracker
  // puts it, as the published simulator's buttons did for a probe without a force sensor.
  double compression_mm = 0.0;  // [0, 20]
};

// Whether `method` can run on the case: on a case split into sub-volumes ([mesh] sub_volumes),
// only the methods that can be stitched (sim::stitchable); the others would solve the whole
// large region in one piece, which takes minutes to build.
bool method_runs_on(const TissueCase& tissue, sim::EngineKind method);

// One trainee's scanning session on one case: probe pose in, deformed tissue and B-scan out.
// The frame thread calls update() then frame_input(); nothing else touches it.
class Session {
 public:
  // `tissue`, `clock` and `jobs` must outlive the session; `jobs` runs the B-scan's parallel
  // work. Allocates all per-frame buffers.
  Session(const TissueCase& tissue, const config::AppSettings& settings, const hal::Clock& clock,
          hal::JobSystem& jobs);

  // Advances one frame with the newest tracker sample. Never throws on bad input: a missing,
  // unhealthy or non-finite sample is rejected and the last good pose is used (before any good
  // pose the probe counts as lifted). Does not allocate.
  FrameOutcome update(const std::optional<hal::PoseSample>& sample);

  // update() in its three stages, for a frame scheduler that may skip the last two when the
  // frame has no time left for them (the screen then shows their previous results):
  // 1. the sample, contact and deformation, within `deadline_us` (< 0: none): the method's work
  //    that can wait stops there (sim::DeformationEngine::step_within; a stitched method still
  //    steps the sub-volumes the probe may touch, a CG at least one iteration);
  FrameOutcome simulate(const std::optional<hal::PoseSample>& sample,
                        hal::TimestampUs deadline_us = -1);
  // 2. the B-scan through the deformed tissue: held when frozen, blank when the probe is off;
  void update_bscan();
  // 3. what the 3D view draws of the tissue: mesh nodes and vessel surfaces.
  void update_view();

  // The controls in force, and changing them. Values out of their ranges are refused with
  // std::invalid_argument naming the control (nothing changes). Allocates when the depth
  // changes (the image grid is rebuilt); call between frames, from the frame thread.
  const BscanControls& controls() const { return controls_; }
  void set_controls(const BscanControls& controls);

  // Views of the latest results for the renderer, valid until the next update() or stage.
  render::FrameInput frame_input(std::int64_t frame_index) const;

  // What a saved image records with it (the trainer's "save"): the case, the method, the probe's
  // pose and the scanner's settings, as PNG text fields. Allocates; call between frames.
  std::vector<render::PngText> image_record() const;

  // What the pose source says is wrong (hal::PoseSource::status_text), shown on screen until
  // changed; empty clears it. Allocates only beyond 160 characters.
  void set_probe_status(std::string_view status) { probe_status_.assign(status); }
  const std::string& probe_status() const { return probe_status_; }

  std::span<const std::uint8_t> bscan() const { return bscan_; }
  int bscan_width_px() const { return grid_.width_px(); }
  int bscan_height_px() const { return grid_.height_px(); }
  bool in_contact() const { return in_contact_; }
  // The slicer in use: the configured one, or the reference when acquiring along scan lines.
  const char* slicer_name() const {
    return fast_slicer_        ? "fast"
           : published_slicer_ ? "published"
           : scan_converter_   ? "reference (scan lines)"
                               : "reference";
  }
  const TissueCase& tissue() const { return tissue_; }

  // The deformation method in use, and a live switch to another: it starts from the current
  // shape (at rest: no velocity). The first switch to a method builds it (the exact FEM's
  // factorisation takes about a second on the default case); later switches are instant. On a
  // case split into sub-volumes ([mesh] sub_volumes) the methods run stitched; those that cannot
  // be (method_runs_on) are refused.
  // Throws std::invalid_argument if the method cannot be built on this case (nothing changes).
  // Call between frames, from the frame thread.
  sim::EngineKind method() const { return engine_->kind(); }
  std::string_view method_name() const { return engine_->name(); }
  void switch_method(sim::EngineKind method);

  // The deformed node positions of the method in use, valid until the next update().
  std::span<const Eigen::Vector3d> engine_positions_mm() const {
    return engine_->deformed_positions_mm();
  }

  // How deep the skin is dented under the probe now, mm (0 at rest).
  double skin_dent_mm() const { return skin_.surface().max_dent_mm(); }

  // The probe as the tissue feels it at `pose` (nullopt: none).
  std::optional<sim::ProbeCollider> probe_collider(
      const std::optional<hal::PoseSample>& pose) const;

 private:
  const TissueCase& tissue_;
  config::AppSettings settings_;
  const hal::Clock& clock_;
  hal::JobSystem& jobs_;
  sim::EngineSettings engine_settings_;
  std::vector<std::uint8_t> skin_nodes_;  // the mesh's skin face: where the probe can touch
  std::array<std::unique_ptr<sim::DeformationEngine>, 6> engines_;  // built on first use
  sim::DeformationEngine* engine_ = nullptr;
  sim::StitchedVolume* stitched_ = nullptr;  // engine_, when it runs stitched
  std::unique_ptr<sim::DeformationEngine> make_method(sim::EngineKind method) const;
  hal::TimestampUs last_update_us_ = -1;
  hal::TimestampUs last_view_us_ = -1;  // when the skin last moved (update_view)
  std::string probe_status_;            // reserved in the constructor
  geometry::TetLocator locator_;
  BscanControls controls_;
  imaging::ProbeGeometry probe_;         // the case's probe at the current depth
  imaging::BscanGrid grid_;              // the display raster
  imaging::BscanGrid acquisition_grid_;  // what is sliced: grid_, or scan lines
  imaging::DisplayMapping display_mapping_;
  std::optional<imaging::ScanConverter> scan_converter_;      // when acquiring along scan lines
  std::vector<std::uint8_t> acquired_;                        // scan-line samples
  std::optional<imaging::FastSlicer> fast_slicer_;            // raster grids, slicer = fast
  std::optional<imaging::PublishedSlicer> published_slicer_;  // raster grids, slicer = published
  std::optional<hal::PoseSample> tracked_pose_;               // last good sample
  std::optional<hal::PoseSample> pose_;  // tracked_pose_ pressed in by controls_.compression_mm
  RefusedPress refused_press_;  // where the tissue is pressed while its method refuses the probe
  sched::PieceBudget sim_budget_{clock_};  // what the method's stoppable work asks (simulate)
  bool in_contact_ = false;
  bool image_shows_tissue_ = false;  // the held image was sliced in contact (matters when frozen)
  std::vector<std::uint8_t> bscan_;
  void rebuild_image_pipeline();
  void slice_in_parallel(const imaging::ProbePose& probe);
  std::vector<render::LineLevel> line_levels_;  // views of the case's wireframe levels
  std::vector<float> node_positions_;
  std::vector<float> node_displacement_;
  DeformedSurfaces structures_;
  DeformableSkin skin_;
  std::vector<render::SurfaceView> surface_views_;  // the structures', then the skin's
};

}  // namespace ultrasim::kiosk
