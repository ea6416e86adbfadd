#pragma once

// The stitching tests' slab of tissue: a regular grid at 2 mm spacing, skin at z = 0, fixed at its
// deepest face, each tet's material chosen from its centroid.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "engine_settings.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim::testing {

struct SlabRegion {
  geometry::GridSpec grid;
  geometry::TetMesh mesh;
  std::vector<Material> materials;
  std::vector<std::uint8_t> fixed;
};

template <typename MaterialAt>  // Material(const Eigen::Vector3d& centroid_mm)
SlabRegion make_slab_region(const Eigen::Vector3i& nodes, MaterialAt material_at) {
  SlabRegion r;
  r.grid.nodes = nodes;
  r.grid.spacing_mm = Eigen::Vector3d::Constant(2.0);
  r.mesh = geometry::make_grid_tet_mesh(r.grid);
  const auto& p = r.mesh.rest_positions_mm;
  for (const auto& t : r.mesh.tets) {
    r.materials.push_back(material_at((p[t[0]] + p[t[1]] + p[t[2]] + p[t[3]]) / 4.0));
  }
  const double deepest = 2.0 * (nodes.z() - 1);
  r.fixed.assign(p.size(), 0);
  for (std::size_t n = 0; n < p.size(); ++n) r.fixed[n] = p[n].z() == deepest;
  return r;
}

// The stitching tests' slab: fat in its top 4 mm over muscle.
inline SlabRegion make_fat_over_muscle_slab(const Eigen::Vector3i& nodes) {
  return make_slab_region(nodes, [](const Eigen::Vector3d& c) {
    return c.z() < 4 ? Material{1, "fat", 20.0, 0.45} : Material{2, "muscle", 50.0, 0.45};
  });
}

// The largest node displacement (max over nodes of the 3-vector norm), mm.
inline double max_norm(const Eigen::VectorXd& u_mm) {
  double m = 0.0;
  for (Eigen::Index i = 0; i < u_mm.size(); i += 3) m = std::max(m, u_mm.segment<3>(i).norm());
  return m;
}

using ultrasim::testing::stick_contact;  // engine_settings.hpp says why the stitching tests use it

}  // namespace ultrasim::sim::testing
