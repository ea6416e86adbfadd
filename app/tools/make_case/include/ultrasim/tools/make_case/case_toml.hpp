#pragma once

// case.toml of the default case, in the format of docs/case-format.md.

#include <Eigen/Core>
#include <string>

namespace ultrasim::tools {

// The text of case.toml for the default upper-arm case whose volumes cover
// [region_min_mm, region_max_mm] (voxel centres, mm). Materials carry literature-based values
// with their sources in comments. Deterministic; allocates the string.
std::string default_case_toml(const Eigen::Vector3d& region_min_mm,
                              const Eigen::Vector3d& region_max_mm);

}  // namespace ultrasim::tools
