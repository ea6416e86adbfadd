#pragma once

// The sim tests' tissue block: 40 × 20 × 20 mm, skin at z = 0, fixed on its deepest face
// (z = 20), with each tet's material chosen from its centroid.

#include <cstdint>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim::testing {

struct Block {
  geometry::TetMesh mesh;
  std::vector<Material> materials;
  std::vector<std::uint8_t> fixed;
};

template <typename MaterialAt>  // Material(const Eigen::Vector3d& centroid_mm)
Block make_block(const Eigen::Vector3i& nodes, MaterialAt material_at) {
  Block b;
  b.mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
      Eigen::Vector3d(-20, -10, 0), Eigen::Vector3d(20, 10, 20), nodes));
  const auto& p = b.mesh.rest_positions_mm;
  for (const auto& t : b.mesh.tets) {
    b.materials.push_back(material_at((p[t[0]] + p[t[1]] + p[t[2]] + p[t[3]]) / 4.0));
  }
  b.fixed.assign(p.size(), 0);
  for (int n = 0; n < b.mesh.node_count(); ++n) b.fixed[n] = p[n].z() == 20.0;
  return b;
}

}  // namespace ultrasim::sim::testing
