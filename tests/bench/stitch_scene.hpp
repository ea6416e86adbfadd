#pragma once

// The stitching benchmarks' scene (stitch_bench, stitch_price): a slab of tissue at 2 mm
// spacing, fat over muscle, fixed at its deepest face, pressed by the published sphere probe.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "engine_settings.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::bench {

constexpr double kStitchSpacingMm = 2.0;
constexpr double kSphereRadiusMm = 8.0;  // the published collider

struct Region {
  geometry::GridSpec grid;
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed;
};

// side × side × depth nodes; the fat is the top 8 mm. Allocates.
// The price of stitching is measured under the published stick contact (engine_settings.hpp says
// why).
using ultrasim::testing::stick_contact;

inline Region make_region(int side, int depth) {
  Region r;
  r.grid.nodes = {side, side, depth};
  r.grid.spacing_mm = Eigen::Vector3d::Constant(kStitchSpacingMm);
  r.mesh = geometry::make_grid_tet_mesh(r.grid);
  const auto& p = r.mesh.rest_positions_mm;
  for (const auto& t : r.mesh.tets) {
    const double z = (p[t[0]].z() + p[t[1]].z() + p[t[2]].z() + p[t[3]].z()) / 4;
    r.materials.push_back(z < 8 ? sim::Material{2, "fat", 20.0, 0.45}
                                : sim::Material{3, "muscle", 50.0, 0.45});
  }
  const double deepest = kStitchSpacingMm * (depth - 1);
  r.fixed.assign(p.size(), 0);
  for (std::size_t n = 0; n < p.size(); ++n) r.fixed[n] = p[n].z() == deepest;
  return r;
}

// The sphere with its lowest point `depth_mm` below the skin at (x, y).
inline sim::ProbeCollider sphere_probe(double x_mm, double y_mm, double depth_mm) {
  return sim::ProbeCollider::sphere(sim::SphereCollider{
      Eigen::Vector3d(x_mm, y_mm, depth_mm - kSphereRadiusMm), kSphereRadiusMm});
}

// The largest node displacement (max over nodes of the 3-vector norm), mm.
inline double max_norm(const Eigen::VectorXd& u_mm) {
  double m = 0.0;
  for (Eigen::Index i = 0; i < u_mm.size(); i += 3) m = std::max(m, u_mm.segment<3>(i).norm());
  return m;
}

}  // namespace ultrasim::bench
