#pragma once

// The reference for a solve that slides held nodes in their tangent planes (the PCG FEM's
// filtered CG, the fine correction's): the frame's problem with the engine's contacts as they are,
// solved by a fresh sparse factorisation in the coordinates of the directions each node may move,
// independent of any projection. u = u₀ + B y, B's columns: the three axes of a node the engine
// does not hold, two tangents of one it holds along its normal only (sliding_hold()), none of a
// node held in full; (Bᵀ K B) y = Bᵀ (f_μ − K u₀), f_μ the sliding nodes' friction.

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <vector>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim::testing {

inline Eigen::VectorXd constrained_equilibrium(const DeformationEngine& engine) {
  const Eigen::SparseMatrix<double, Eigen::RowMajor> k = engine.rest_stiffness_mn_per_mm();
  const Eigen::VectorXd& u0 = engine.displacements_mm();
  const int nodes = static_cast<int>(u0.size() / 3);
  std::vector<Eigen::Triplet<double>> basis;
  Eigen::VectorXd load = -(k * u0);
  int columns = 0;
  for (int node = 0; node < nodes; ++node) {
    const DeformationEngine::SlidingHold* hold = engine.sliding_hold(node);
    if (hold != nullptr) {
      // Any two unit vectors across the normal.
      const Eigen::Vector3d t1 = hold->normal.unitOrthogonal();
      const Eigen::Vector3d t2 = hold->normal.cross(t1);
      for (const Eigen::Vector3d& t : {t1, t2}) {
        for (int d = 0; d < 3; ++d) basis.emplace_back(3 * node + d, columns, t[d]);
        ++columns;
      }
      load.segment<3>(3 * node) += hold->friction_mn;
    } else if (!engine.holds_node(node)) {
      for (int d = 0; d < 3; ++d) basis.emplace_back(3 * node + d, columns++, 1.0);
    }
  }
  Eigen::SparseMatrix<double> b(3 * nodes, columns);
  b.setFromTriplets(basis.begin(), basis.end());
  const Eigen::SparseMatrix<double> kc = Eigen::SparseMatrix<double>(k);
  const Eigen::SparseMatrix<double> reduced = b.transpose() * kc * b;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(reduced);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd rhs = b.transpose() * load;
  return u0 + b * ldlt.solve(rhs);
}

}  // namespace ultrasim::sim::testing
