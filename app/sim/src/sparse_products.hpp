#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace ultrasim::sim::detail {

// out = (K + diag(d)) p for a symmetric K and a p that is zero but at a few entries (what a
// solve's constraints hold): K's rows at p's nonzero entries, read as its columns, instead of
// all of K. `diagonal` may be null (no d). The same sum as the full product to rounding (another
// order of addition); out is resized to K's rows.
inline void symmetric_times_sparse_vector(const Eigen::SparseMatrix<double, Eigen::RowMajor>& k,
                                          const Eigen::VectorXd* diagonal, const Eigen::VectorXd& p,
                                          Eigen::VectorXd& out) {
  out.setZero(k.rows());
  for (Eigen::Index j = 0; j < p.size(); ++j) {
    const double pj = p[j];
    if (pj == 0.0) continue;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(k, j); it; ++it) {
      out[it.col()] += it.value() * pj;
    }
    if (diagonal != nullptr) out[j] += (*diagonal)[j] * pj;
  }
}

}  // namespace ultrasim::sim::detail
