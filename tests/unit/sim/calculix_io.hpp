#pragma once

// Writing a static linear-elastic problem as a CalculiX input deck, running ccx, and reading its
// displacements back: the independent reference for the FEM solvers' accuracy tests.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/exact_fem.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim::test {

struct NodalLoad {
  int node = 0;
  Eigen::Vector3d force_mn = Eigen::Vector3d::Zero();
};

// One static problem. CalculiX is unit-free: lengths in mm and E in kPa make its forces mN,
// the same units as our K u.
struct CalculixProblem {
  const geometry::TetMesh* mesh = nullptr;
  std::span<const Material> tet_materials;
  std::span<const std::uint8_t> fixed_nodes;  // nonzero: all three DOFs held at zero
  std::vector<PrescribedNode> held;           // *BOUNDARY with a value, in the step
  std::vector<NodalLoad> loads;               // *CLOAD, in the step
};

// The .inp text: *NODE, one C3D4 *ELEMENT block and *MATERIAL/*SOLID SECTION per distinct
// material, fixed nodes as *BOUNDARY, one *STATIC step with held values, loads and a *NODE PRINT
// of U. Node and element numbers are ours + 1. Our tets are positively oriented
// ((p1−p0, p2−p0, p3−p0) right-handed), which is what C3D4 wants (ccx rejects the mirror image
// with "nonpositive jacobian").
std::string calculix_input(const CalculixProblem& problem);

// Displacements (mm) of nodes 1..node_count from a ccx .dat holding a *NODE PRINT U block.
// Throws std::runtime_error when the block or a node is missing.
std::vector<Eigen::Vector3d> parse_calculix_displacements(const std::string& dat_text,
                                                          int node_count);

// True when a `ccx` executable is on PATH.
bool calculix_available();

// Writes the problem into a fresh temporary folder, runs `ccx -i job` there and returns the
// displacements. Throws std::runtime_error with ccx's log tail when ccx fails. The folder is
// removed on success and kept (its path in the message) on failure.
std::vector<Eigen::Vector3d> solve_with_calculix(const CalculixProblem& problem);

}  // namespace ultrasim::sim::test
