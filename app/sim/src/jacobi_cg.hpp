#pragma once

#include <Eigen/Core>

namespace ultrasim::sim {

// One update of Jacobi-preconditioned conjugate gradients once the caller has q = A p (the
// product is each solver's own: masked, banded, summed over copies): x += α p, r −= α q,
// z = S M⁻¹ r, p = z + β p, with α = rz / pᵀq and rz updated to rᵀz. `filter` applies S in place:
// the projection onto the directions the solve may move (a filtered CG: a node held only along
// one direction moves in the plane across it); M⁻¹ r leaves that plane where M is not isotropic
// at the node. Returns false and changes nothing when pᵀq is not positive (converged to rounding,
// or A not definite along p). Does not allocate.
template <typename Filter>
bool jacobi_cg_update(const Eigen::VectorXd& inverse_diagonal, const Eigen::VectorXd& q,
                      Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::VectorXd& z,
                      Eigen::VectorXd& p, double& rz, const Filter& filter) {
  const double pq = p.dot(q);
  if (!(pq > 0.0)) return false;
  const double alpha = rz / pq;
  x.noalias() += alpha * p;
  r.noalias() -= alpha * q;
  z = inverse_diagonal.cwiseProduct(r);
  filter(z);
  const double next_rz = r.dot(z);
  p = z + (next_rz / rz) * p;
  rz = next_rz;
  return true;
}

// The same where every direction of a free unknown is free (S = I on r's support).
inline bool jacobi_cg_update(const Eigen::VectorXd& inverse_diagonal, const Eigen::VectorXd& q,
                             Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::VectorXd& z,
                             Eigen::VectorXd& p, double& rz) {
  return jacobi_cg_update(inverse_diagonal, q, x, r, z, p, rz, [](Eigen::VectorXd&) {});
}

}  // namespace ultrasim::sim
