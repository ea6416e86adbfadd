#pragma once

// A box meshed finely where a probe presses and coarsely far from it, for convergence studies
// that need a near half-space: make_grid_tet_mesh's 5-tet split of the unit grid, each node moved
// to graded per-axis coordinates. A monotone map per axis keeps every cell an axis-aligned box
// (only its edge lengths change), so every tet keeps its positive orientation.
//
// The map is uniform over a core, then geometric (a piecewise exponential) rather than a sinh:
// a sinh stretches from the very centre, so the skin nodes under the probe would not be evenly
// spaced and the contact edge would be resolved differently at every depth of indentation.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::sim::testing {

// Node coordinates from 0 outwards: uniform steps of `h` up to at least `core`, then steps
// growing geometrically by `ratio` until at least `extent`. Ascending, first 0.
inline std::vector<double> graded_axis(double h, double core, double extent, double ratio) {
  if (!(h > 0.0 && core >= 0.0 && extent > core && ratio >= 1.0)) {
    throw std::invalid_argument("graded_axis: need h > 0, 0 <= core < extent, ratio >= 1");
  }
  std::vector<double> x = {0.0};
  while (x.back() < core - 1e-9 * h) x.push_back(x.back() + h);
  double step = h;
  while (x.back() < extent) {
    step *= ratio;
    x.push_back(x.back() + step);
  }
  return x;
}

// The same axis mirrored about 0: −x_n … 0 … x_n.
inline std::vector<double> mirrored(const std::vector<double>& half) {
  std::vector<double> x;
  for (std::size_t i = half.size(); i-- > 1;) x.push_back(-half[i]);
  x.insert(x.end(), half.begin(), half.end());
  return x;
}

struct GradedBlock {
  geometry::TetMesh mesh;
  std::vector<std::uint8_t> fixed;  // the face at the largest z
};

// The tensor-product grid of the given ascending coordinates, split into 5-tet cells, fixed on
// its deepest face (z = zs.back()).
inline GradedBlock make_graded_block(const std::vector<double>& xs, const std::vector<double>& ys,
                                     const std::vector<double>& zs) {
  const Eigen::Vector3i nodes(static_cast<int>(xs.size()), static_cast<int>(ys.size()),
                              static_cast<int>(zs.size()));
  GradedBlock b;
  // The unit grid: node (i, j, k) at (i, j, k); its coordinates index the graded axes.
  b.mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
      Eigen::Vector3d::Zero(), (nodes - Eigen::Vector3i::Ones()).cast<double>(), nodes));
  b.fixed.assign(b.mesh.rest_positions_mm.size(), 0);
  for (std::size_t n = 0; n < b.mesh.rest_positions_mm.size(); ++n) {
    Eigen::Vector3d& p = b.mesh.rest_positions_mm[n];
    const auto i = static_cast<std::size_t>(std::lround(p.x()));
    const auto j = static_cast<std::size_t>(std::lround(p.y()));
    const auto k = static_cast<std::size_t>(std::lround(p.z()));
    p = Eigen::Vector3d(xs[i], ys[j], zs[k]);
    b.fixed[n] = k + 1 == zs.size();
  }
  return b;
}

}  // namespace ultrasim::sim::testing
