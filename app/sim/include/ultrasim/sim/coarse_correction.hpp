#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/sub_volume_split.hpp"

namespace ultrasim::sim {

// The coarse level of a stitched volume (two-level Schwarz). Zero-length springs let a
// disturbance cross one seam per exchange, so a region of many sub-volumes relaxes like a block
// Jacobi iteration: slowly, and slower the more sub-volumes there are. Once a frame, after the
// sub-volumes have stepped, this finds the displacement among the smooth fields of a coarse grid
// (trilinear over nodes at the grid's ends and the middle of each overlap band) that lowers the
// whole region's elastic energy most, and adds it to every copy of every free node:
//   (Pᵀ D K D P) Δc = Pᵀ D f,   Δu = D P Δc,
// P the trilinear interpolation, D the nodes neither fixed nor held by the probe, K and f the
// sub-volumes' rest stiffnesses and elastic forces summed over their copies (the overlap's
// stiffness split among its copies makes them add up to one piece; the seams' springs cancel, as
// every copy of a node moves alike). For the linear FEM it is the exact Galerkin coarse step;
// for the MSDS its stiffness is linearised about rest and its forces are the springs' own.
//
// Per sub-volume the coarse stiffness Pᵀ D K D P is kept (fixed nodes only, built once) and
// changed where the probe holds nodes by the held rows alone; each sub-volume's share of the
// coarse residual is kept too, recomputed when it steps and updated by the correction's
// (linear) effect otherwise, so sub-volumes that do not step cost nothing.
//
// Threads: update() and apply() for different sub-volumes may run in parallel; solve() alone.
// Nothing allocates after construction.
class CoarseCorrection {
 public:
  // The region's grid, its sub-volumes' boxes and engines (in the same order; their
  // holds_node() at construction says which nodes are fixed). Allocates.
  CoarseCorrection(const geometry::GridSpec& grid, std::span<const SubVolumeBox> boxes,
                   std::span<const DeformationEngine* const> engines);

  int coarse_node_count() const { return nodes_.prod(); }

  // After sub-volume `sub` stepped (or its shape was set): its held nodes and share of the
  // residual, from its engine as it is now.
  void update(int sub, const DeformationEngine& engine);
  // The seams' pull on a copy of a shared node (sub-volume `sub`, its node `local_node`), mN, as
  // the copies lie now: their share of the residual. Given for every copy before each solve();
  // forgotten after it. (The pulls on a node's copies cancel, unless the probe holds some copies
  // and not others; left out, such a node would bias every coarse step.)
  void add_seam_force(int sub, int local_node, const Eigen::Vector3d& force_mn);
  // Whether the last update() left the copy out of the coarse step (fixed, held, or frozen).
  bool left_out(int sub, int local_node) const { return subs_[sub].held[local_node] != 0; }
  // A seam whose copies the coarse step moves unevenly (some left out): its springs resist the
  // step, with `stiffness_mn_per_mm` summed over the pairs of one moving and one still copy.
  // Given before each solve(); forgotten after it.
  void add_uneven_seam(const Eigen::Vector3i& grid_node, double stiffness_mn_per_mm);
  // The coarse step from every sub-volume's share; false if the coarse system could not be
  // factored (nothing is corrected then).
  bool solve();
  // The largest nodal move the last solve() asks of sub-volume `sub`, mm (before the held and
  // fixed nodes are left out).
  double largest_move_mm(int sub) const;
  // Moves the sub-volume's free nodes by its part of the last solve() and updates its share of
  // the residual to match.
  void apply(int sub, DeformationEngine& engine);

 private:
  // A grid node's trilinear weights: 8 coarse nodes (global index) and their weights.
  struct Weights {
    std::array<int, 8> coarse{};
    std::array<double, 8> weight{};
  };
  struct Sub {
    Eigen::Vector3i first_node;  // the box's
    Eigen::Vector3i nodes;
    Eigen::Vector3i coarse_first;  // the coarse nodes its nodes' weights reach
    Eigen::Vector3i coarse_nodes;
    Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness;
    std::vector<Weights> weights;           // per local node: its local coarse nodes and weights
    std::vector<std::uint8_t> fixed;        // per local node
    std::vector<std::uint8_t> held;         // per local node, fixed included, as of update()
    std::vector<int> held_free;             // held nodes that are not fixed
    Eigen::MatrixXd rest_coarse_stiffness;  // fixed nodes left out
    Eigen::MatrixXd coarse_stiffness;       // held nodes left out too; valid if held_free
    Eigen::VectorXd residual;               // Pᵀ D f, local coarse DOFs
    Eigen::VectorXd seam_residual;          // Pᵀ D of the seams' pull, this frame
    Eigen::VectorXd correction;             // the last solve()'s Δc, local coarse DOFs
    Eigen::VectorXd forces, move, row;      // scratch
  };

  // The sub-volume's coarse stiffness as of update(): the rest one unless the probe holds nodes.
  static const Eigen::MatrixXd& coarse_stiffness(const Sub& sub) {
    return sub.held_free.empty() ? sub.rest_coarse_stiffness : sub.coarse_stiffness;
  }
  Weights weights(const Eigen::Vector3i& grid_node) const;
  // The local coarse DOF of a global coarse node's axis `d` in `sub`.
  int local_dof(const Sub& sub, int coarse_node, int d) const;
  int global_dof(const Sub& sub, int local_dof) const;
  Weights local_weights(const Sub& sub, int local_node) const;
  void build_rest_coarse_stiffness(Sub& sub) const;
  void update_held_coarse_stiffness(Sub& sub) const;

  Eigen::Vector3i nodes_;  // coarse nodes per axis
  // Per axis and grid node index: the coarse interval it lies in and its weight toward the
  // interval's upper end.
  std::array<std::vector<int>, 3> interval_;
  std::array<std::vector<double>, 3> upper_weight_;
  std::vector<Sub> subs_;
  Eigen::MatrixXd rest_stiffness_;  // Σ over sub-volumes of their rest coarse stiffness
  Eigen::MatrixXd stiffness_;       // this frame's
  Eigen::MatrixXd seam_stiffness_;  // this frame's uneven seams
  Eigen::VectorXd residual_, correction_;
  Eigen::LLT<Eigen::MatrixXd> factor_;
};

}  // namespace ultrasim::sim
