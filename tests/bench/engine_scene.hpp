#pragma once

// The deformation benchmarks' scene (engine_bench, engine_budget_bench): a soft block under a
// linear probe face pressed 4 mm and then sliding, and the error measure both report.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <map>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::bench {

struct Block {
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed, skin;
};

// The default case's region, 60 × 40 × 45 mm, fixed at depth 45: fat over muscle. Built once per
// grid size and kept (set-up is not what the benchmarks time).
inline const Block& block(int nx, int ny, int nz) {
  static std::map<long, Block> blocks;
  Block& b = blocks[(nx * 1000L + ny) * 1000L + nz];
  if (!b.mesh.tets.empty()) return b;
  b.mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-30, -20, 0}, {30, 20, 45}, {nx, ny, nz}));
  const auto& p = b.mesh.rest_positions_mm;
  for (const auto& t : b.mesh.tets) {
    const double z = (p[t[0]].z() + p[t[1]].z() + p[t[2]].z() + p[t[3]].z()) / 4;
    b.materials.push_back(z < 15 ? sim::Material{2, "fat", 20.0, 0.45}
                                 : sim::Material{3, "muscle", 50.0, 0.45});
  }
  b.fixed.assign(p.size(), 0);
  b.skin.assign(p.size(), 0);
  for (std::size_t n = 0; n < p.size(); ++n) {
    b.fixed[n] = p[n].z() == 45.0;
    b.skin[n] = p[n].z() == 0.0;
  }
  return b;
}

// Frames run untimed before the error is measured: the press and one slide across and back.
constexpr int kAccuracyFrames = 60;
constexpr double kFrameDtS = 1.0 / 60.0;

// The probe at a frame: 4 mm deep after a 20-frame press, then sliding ±5 mm at 0.5 mm a frame.
inline sim::ProbeCollider probe_at(int frame) {
  const double depth = std::min(4.0, 0.2 * frame);
  const int phase = std::max(0, frame - 20) % 40;
  const double x = phase < 20 ? -5.0 + 0.5 * phase : 5.0 - 0.5 * (phase - 20);
  return sim::ProbeCollider::linear_face(Eigen::Vector3d(x, 0.3, depth),
                                         Eigen::Quaterniond::Identity(), 38.0, 10.0, 2.0);
}

// The error both benchmarks report: the largest displacement component's difference over the
// largest reference component (max norm, relative).
inline double relative_max_error(const Eigen::VectorXd& got_mm, const Eigen::VectorXd& want_mm) {
  return (got_mm - want_mm).lpNorm<Eigen::Infinity>() / want_mm.lpNorm<Eigen::Infinity>();
}

}  // namespace ultrasim::bench
