#pragma once

// case.toml of the synthetic upper-arm cases, in the format of docs/case-format.md.

#include <Eigen/Core>
#include <array>
#include <string>

namespace ultrasim::tools {

// What differs between the synthetic arm's cases: the name, the tet grid and its split, the
// scripted scan.
struct ArmCaseLayout {
  std::string name = "default-upper-arm";
  std::string description = "synthetic upper arm: vein beside artery, nerve, humerus";
  std::array<int, 3> nodes{37, 9, 28};
  std::string nodes_comment = "1.67 mm in the image plane: the vein is 4.4 mm deep";
  std::array<int, 3> sub_volumes{1, 1, 1};  // [1, 1, 1]: one piece (not written)
  // Along the limb, centred between vein (x = -8) and artery (x = +6) so both stay in view.
  Eigen::Vector3d scan_start_mm{-2.0, -12.0, 0.0};
  Eigen::Vector3d scan_end_mm{-2.0, 12.0, 0.0};
};

// The large case: the same arm over 120 × 120 × 45 mm, meshed as the published 25 stitched
// sub-volumes of 15³ nodes (84,375 nodes in all, 343,000 tets), scanned 80 mm along the limb.
ArmCaseLayout large_arm_layout();

// The text of case.toml for an upper-arm case whose volumes cover [region_min_mm,
// region_max_mm] (voxel centres, mm). Materials carry literature-based values with their sources
// in comments. Deterministic; allocates the string.
std::string default_case_toml(const Eigen::Vector3d& region_min_mm,
                              const Eigen::Vector3d& region_max_mm,
                              const ArmCaseLayout& layout = {});

}  // namespace ultrasim::tools
