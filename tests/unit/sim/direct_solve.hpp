#pragma once

// The exact FEM tests' reference: a fresh sparse factorisation of the reduced system, with the
// fixed nodes' DOFs and the given DOF values eliminated. Independent of ExactFem's factor and of
// its condensation.

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cstdint>
#include <utility>
#include <vector>

namespace ultrasim::sim::testing {

// K u = f on the unknown DOFs; `known` holds (DOF, value) pairs; `load_mn` has one entry per DOF.
inline Eigen::VectorXd direct_solve_with_known_dofs(
    const Eigen::SparseMatrix<double, Eigen::RowMajor>& k, const std::vector<std::uint8_t>& fixed,
    const std::vector<std::pair<int, double>>& known, const Eigen::VectorXd& load_mn) {
  const int dofs = static_cast<int>(k.rows());
  Eigen::VectorXd u = Eigen::VectorXd::Zero(dofs);
  std::vector<std::uint8_t> is_known(dofs, 0);
  for (std::size_t n = 0; n < fixed.size(); ++n)
    if (fixed[n]) is_known[3 * n] = is_known[3 * n + 1] = is_known[3 * n + 2] = 1;
  for (const auto& [dof, value] : known) {
    u[dof] = value;
    is_known[dof] = 1;
  }
  std::vector<int> index(dofs, -1);
  int count = 0;
  for (int d = 0; d < dofs; ++d)
    if (!is_known[d]) index[d] = count++;
  const Eigen::VectorXd rhs_full = load_mn - k * u;
  Eigen::VectorXd rhs(count);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int r = 0; r < dofs; ++r) {
    if (index[r] < 0) continue;
    rhs[index[r]] = rhs_full[r];
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(k, r); it; ++it)
      if (index[it.col()] >= 0) triplets.emplace_back(index[r], index[it.col()], it.value());
  }
  Eigen::SparseMatrix<double> kr(count, count);
  kr.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(kr);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd ur = ldlt.solve(rhs);
  for (int d = 0; d < dofs; ++d)
    if (index[d] >= 0) u[d] = ur[index[d]];
  return u;
}

}  // namespace ultrasim::sim::testing
