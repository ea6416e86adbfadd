#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::tools {

// A case made from a real reconstructed 3D ultrasound volume (e.g. PLUS's freehand
// reconstruction) before any segmentation exists: one homogeneous soft tissue everywhere.
//
// The simulated region is where the volume holds data: the bounding box of non-zero voxels,
// less a margin, starting at the depth (+z) by which `min_coverage` of its (x, y) columns have
// begun to hold data, so the probe rests on tissue rather than on the ragged edge of the sweep.
// The probe rests on that top face and sweeps along +y through the middle of the region.
struct VolumeCaseSettings {
  std::string name = "real-volume";
  std::string description;
  double min_coverage = 0.8;         // fraction of non-zero voxels that makes a layer "tissue"
  double margin_mm = 2.0;            // shrink the data box by this on every side but the top
  double node_spacing_mm = 2.5;      // mesh resolution (nodes per axis follow from the region)
  double youngs_modulus_kpa = 30.0;  // soft tissue (muscle/fat range: 10–100 kPa)
  double poisson_ratio = 0.45;       // nearly incompressible, as soft tissue is
  double probe_width_mm = 38.0;      // clipped to the region's width
  double probe_depth_mm = 40.0;      // clipped to the region's depth
  double press_depth_mm = 6.0;
};

struct VolumeCase {
  config::CaseSettings settings;         // paths relative to the case folder
  imaging::Volume<std::uint8_t> labels;  // every voxel: label 3 (one tissue)
};

// Derives the case for `volume` (see VolumeCaseSettings). Throws std::invalid_argument if the
// volume holds no usable data. Allocates.
VolumeCase make_volume_case(const imaging::Volume<std::uint8_t>& volume,
                            const VolumeCaseSettings& settings);

// Writes <dir>/volume.mha (the echo volume, recompressed), <dir>/labels.mha and <dir>/case.toml.
void write_volume_case(const std::filesystem::path& dir,
                       const imaging::Volume<std::uint8_t>& volume, const VolumeCase& c);

}  // namespace ultrasim::tools
