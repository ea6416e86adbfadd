#pragma once

// The corotational FEM's turn check (CorotationalFem::update_rotations): how far each tet's
// rotation has turned from the one it holds. Two implementations of the same arithmetic: a
// portable one (one tet at a time) and an AVX2 one (four tets in the lanes of __m256d, picked at
// run time where the CPU has AVX2). Both do the same IEEE operations in the same order (no FMA
// contraction, correctly rounded division and square root), so they give bitwise the same turns
// (rotation_turns_test.cpp); reference_turn is the check as written with Eigen, the reference
// both are held to.

#include <Eigen/Core>
#include <limits>
#include <span>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::sim::corotational_detail {

// A stretch of the tet along one of its rotation's axes at or below this has collapsed: its
// rotation is taken again.
inline constexpr double kCollapsedStretch = 0.1;

// What the turn check reads: the tets, their nodes' rest positions and displacements (node-major,
// mm), each tet's shape-function gradients (column a: node a's, 1/mm) and the rotation it holds.
struct TurnInputs {
  const geometry::Tet* tets = nullptr;
  const Eigen::Vector3d* rest_mm = nullptr;
  const double* u_mm = nullptr;
  const Eigen::Matrix<double, 3, 4>* shape_gradients = nullptr;
  const Eigen::Matrix3d* rotations = nullptr;
};

// How far, in radians to first order, the rotation of a tet's deformation gradient f has turned
// from its rotation r. With f = r S and S symmetric positive definite, r is exactly f's polar
// rotation, however S changed: a tet that only stretched or squeezed more keeps its rotation. A
// small turn by θ about axis k adds θ (s_i + s_j) to component k of the axial vector of rᵀ f
// (s_i, s_j: the stretches along the other two axes, the diagonal of its symmetric part), so each
// component over its pair of stretches is that component of the turn, however unequal the
// stretches. Infinite (take the rotation again) for an inverted or collapsed f, or one whose
// symmetric part in r's frame is not positive definite (r is then not its rotation at all: a
// half turn away, say).
inline double reference_turn(const Eigen::Matrix3d& r, const Eigen::Matrix3d& f) {
  const Eigen::Matrix3d s = r.transpose() * f;
  const Eigen::Matrix3d symmetric = 0.5 * (s + s.transpose());
  // Positive definite (the leading minors), each stretch above collapse, f not inverted.
  const double minor2 = symmetric(0, 0) * symmetric(1, 1) - symmetric(0, 1) * symmetric(1, 0);
  if (!(symmetric.diagonal().minCoeff() > kCollapsedStretch) || !(minor2 > 0.0) ||
      !(symmetric.determinant() > 0.0) || !(f.determinant() > 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  const Eigen::Vector3d d = symmetric.diagonal();
  const Eigen::Vector3d turn((s(2, 1) - s(1, 2)) / (d[1] + d[2]),
                             (s(0, 2) - s(2, 0)) / (d[0] + d[2]),
                             (s(1, 0) - s(0, 1)) / (d[0] + d[1]));
  return turn.norm();
}

// turns[t] for each tet index t in `tets` (any order, repeats allowed): the turn of tet t's
// deformation gradient F = Σ_b (x_b − x_0) g_bᵀ from its rotation, as reference_turn. Reads and
// writes nothing else; any thread, on disjoint index lists at once.
using TurnKernel = void (*)(const TurnInputs& in, std::span<const int> tets, double* turns);

// One tet at a time.
TurnKernel portable_turn_kernel();
// The fastest this CPU runs (AVX2 where it has it), the same turns to the bit.
TurnKernel fastest_turn_kernel();

}  // namespace ultrasim::sim::corotational_detail
