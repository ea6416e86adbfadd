#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/imaging/settings.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::config {

// One face of the simulated region's bounding box (docs/case-format.md, [mesh] fixed_faces).
enum class BoxFace { kXMin, kXMax, kYMin, kYMax, kZMin, kZMax };

// [mesh]: the regular tetrahedral grid laid over the case. Millimetres in patient space.
struct CaseMesh {
  std::array<int, 3> nodes{2, 2, 2};  // grid nodes along x, y, z; each in [2, 512]
  // The simulated region; both set or both unset (then: the volume's extent). min < max per axis.
  std::optional<std::array<double, 3>> region_min_mm;
  std::optional<std::array<double, 3>> region_max_mm;
  std::vector<BoxFace> fixed_faces;  // nodes on these faces do not move; no duplicates
  std::vector<int> fix_label;        // nodes inside these labels (e.g. bone) do not move either
  // How a tet cut by several labels gets its material (sim::MaterialMixing).
  sim::MaterialMixing material_mixing = sim::MaterialMixing::kCentroid;
  // Volume stitching (sim::StitchedVolume): the grid split into sub-volumes along x, y, z, each
  // in [1, 64] (1, 1, 1: one piece), neighbours sharing overlap_nodes node layers, in [1, 8].
  // Every box must keep more than overlap_nodes nodes on a split axis, and each must hold fixed
  // nodes (the app refuses a split that leaves one free to float).
  std::array<int, 3> sub_volumes{1, 1, 1};
  int overlap_nodes = 2;
};

// [scan]: the scripted probe's sweep over the case, for headless runs. Millimetres, patient space.
struct CaseScan {
  std::array<double, 3> start_mm{0.0, 0.0, 0.0};  // probe face centre at the start of the sweep
  std::array<double, 3> end_mm{0.0, 0.0, 0.0};    // ... and at its end
  double press_depth_mm = 0.0;                    // how far the probe presses in, [0, 50]
};

// A validated case.toml (docs/case-format.md). Paths are resolved against the case folder and
// were checked to exist when loaded.
struct CaseSettings {
  std::string name;                      // [case] name, shown in the case list
  std::string description;               // [case] description (may be empty)
  std::filesystem::path volume_path;     // [case] volume: B-mode echo volume (.mha)
  std::filesystem::path labels_path;     // [case] labels: tissue label volume (.mha), same grid
  CaseMesh mesh;                         // [mesh]
  std::vector<sim::Material> materials;  // [[materials]]: at least one, labels unique
  imaging::ProbeGeometry probe;          // [probe]
  CaseScan scan;                         // [scan]
};

// Reads and validates a case. case_dir_or_toml_path is either the case folder (then its case.toml
// is read) or the case.toml itself. Relative volume/labels paths are resolved against the folder
// holding case.toml, and both files must exist. Returns a complete struct or throws ConfigError.
// Allocates; safe to call from any thread.
CaseSettings load_case_settings(const std::filesystem::path& case_dir_or_toml_path);

// As load_case_settings, from TOML text already in memory: source_name is used in error messages,
// case_dir is the folder that relative paths are resolved against. Allocates.
CaseSettings parse_case_settings(std::string_view toml_text, std::string_view source_name,
                                 const std::filesystem::path& case_dir);

// The case.toml text for these settings, each key preceded by a one-line comment; paths inside
// case_dir are written relative to it. parse_case_settings() of the result (with the same
// case_dir) gives back the same values. Does not validate. Allocates.
std::string format_case_toml(const CaseSettings& settings, const std::filesystem::path& case_dir);

}  // namespace ultrasim::config
