#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>
#include <span>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::geometry {

// A tet's edges from its node 0, as columns: [x1 − x0, x2 − x0, x3 − x0]. Inline: the slicers and
// the locator build one per tet every frame.
inline Eigen::Matrix3d tet_edge_matrix(std::span<const Eigen::Vector3d> positions_mm,
                                       const Tet& tet) {
  const Eigen::Vector3d& p0 = positions_mm[tet[0]];
  Eigen::Matrix3d edges;
  edges << positions_mm[tet[1]] - p0, positions_mm[tet[2]] - p0, positions_mm[tet[3]] - p0;
  return edges;
}

// Whether a tet with these edges can be located in and sampled (TetLocator's rule; the slicers
// share it to the bit, so all skip the same tets): finite and positively oriented, its
// determinant above 1e-12 of the product of its edges' lengths.
inline bool usable_tet(const Eigen::Matrix3d& edges) {
  const double det = edges.determinant();
  const double scale = edges.colwise().norm().prod();
  return std::isfinite(det) && det > 1e-12 * scale;
}

}  // namespace ultrasim::geometry
