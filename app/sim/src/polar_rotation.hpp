#pragma once

// The rotation the corotational FEM takes of a tet's deformation gradient (CorotationalFem).

#include <Eigen/Core>

namespace ultrasim::sim::corotational_detail {

// The proper rotation closest to f (maximising tr(Rᵀ f) over det R = +1), by SVD: for an inverted
// f the column of U belonging to the smallest singular value is flipped, so the rotation never
// becomes a reflection (Irving et al. 2004). ~0.8 µs; the reference for polar_rotation().
Eigen::Matrix3d rotation_by_svd(const Eigen::Matrix3d& f);

// The same rotation, robust to inverted and collapsed tets (identity for a non-finite f): by
// Newton's iteration for a well-conditioned f (an inverted one's orthogonal factor then flipped
// across its smallest stretch), by SVD for a nearly collapsed one.
Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f);

}  // namespace ultrasim::sim::corotational_detail
