#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
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
#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::kiosk {

// What one frame did, for the stats report.
struct FrameOutcome {
  bool pose_rejected = false;  // the sample was missing, unhealthy or non-finite: last good kept
  bool in_contact = false;     // the probe touches the tissue, so there is an image
  sim::FemStepStats fem;
  std::int64_t sim_us = 0;       // collision + FEM solve
  std::int64_t slice_us = 0;     // B-scan synthesis and display mapping
  std::int64_t surfaces_us = 0;  // vessel surfaces following the tissue
};

// The scanner's controls a trainee can change while scanning.
struct BscanControls {
  double gain_db = 0.0;                                        // [-40, 40]
  std::array<double, imaging::kTgcSliders> tgc_db{};           // each [-30, 30]
  double dynamic_range_db = imaging::kRecordedDynamicRangeDb;  // [10, 100]
  double depth_mm = 40.0;                                      // [10, 300]
  bool frozen = false;  // image held; the tissue still follows the probe
};

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

  // The controls in force, and changing them. Values out of their ranges are refused with
  // std::invalid_argument naming the control (nothing changes). Allocates when the depth
  // changes (the image grid is rebuilt); call between frames, from the frame thread.
  const BscanControls& controls() const { return controls_; }
  void set_controls(const BscanControls& controls);

  // Views of this frame's results for the renderer, valid until the next update().
  render::FrameInput frame_input(std::int64_t frame_index) const;

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

 private:
  const TissueCase& tissue_;
  config::AppSettings settings_;
  const hal::Clock& clock_;
  hal::JobSystem& jobs_;
  sim::LinearFem fem_;
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
  std::optional<hal::PoseSample> pose_;                       // last good pose
  bool in_contact_ = false;
  bool image_shows_tissue_ = false;  // the held image was sliced in contact (matters when frozen)
  std::vector<std::uint8_t> bscan_;
  void rebuild_image_pipeline();
  void slice_in_parallel(const imaging::ProbePose& probe);
  std::vector<float> node_positions_;
  std::vector<float> node_displacement_;
  DeformedSurfaces structures_;
};

}  // namespace ultrasim::kiosk
