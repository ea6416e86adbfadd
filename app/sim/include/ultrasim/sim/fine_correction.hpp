#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/node_block_matrix.hpp"
#include "ultrasim/sim/sliding_nodes.hpp"

namespace ultrasim::sim {

// The fine level of a stitched volume: a few conjugate-gradient iterations a frame on the whole
// region as one piece, over the nodes of the sub-volumes that stepped. Seams exchanged once a
// frame let the sub-volumes around a press settle like a block Jacobi iteration, one seam a
// frame; this solves
//   (D K D) Δu = D f,
// K and f the stepped sub-volumes' stiffnesses (each method's tangent where it has its own,
// DeformationEngine::tangent_stiffness_times: the corotational FEM's warped K_R; else the rest
// stiffness) and elastic forces summed over the copies of
// each grid node (the overlap's stiffness split among its copies makes them add up to one
// piece's), D the grid nodes that are neither fixed nor held by the probe in any copy and whose
// every copy stepped (the rest stay where the frame left them), and adds Δu to every copy. A node
// the probe holds along its normal only in some copy (DeformationEngine::sliding_hold) and in no
// copy in full (nor along another normal) moves in its tangent plane, its friction counted in f
// (a filtered CG). For
// the linear (PCG) FEM it is the one-piece solve's own step from the stitched shape; for the
// MSDS the stiffness is linearised about rest, and the step is quasi-static: it moves the tissue
// toward equilibrium, not along the one piece's damped motion. For the corotational FEM it is its
// own step with the rotations its tets hold.
//
// Jacobi-preconditioned (the rest stiffness's diagonal, for every method); the products run per
// sub-volume on the job system and are summed per grid node. Nothing allocates after construction.
// The frame thread calls correct().
class FineCorrection {
 public:
  // Per sub-volume, its local nodes' grid nodes and its engine (rest_stiffness_mn_per_mm is
  // taken now, and whether it multiplies with its own tangent); per grid node, whether it is
  // fixed. Allocates.
  FineCorrection(std::span<const std::vector<int>> grid_nodes,
                 std::span<const DeformationEngine* const> engines,
                 std::span<const std::uint8_t> fixed_grid_nodes);

  struct Result {
    int iterations = 0;
    // ‖r‖ over the corrected nodes when it stopped, over the load's ‖f‖ on every node (the
    // probe's and the fixed base's reactions included).
    double relative_residual = 0.0;
    double largest_move_mm = 0.0;
  };
  // `engines`: the constructor's (whether each multiplies with its own tangent was asked there).
  // At most `iterations` iterations over the sub-volumes flagged in `stepped`, then moves their
  // free nodes. Fewer once the free nodes' imbalance is below `relative_tolerance` of the load
  // (none when the tissue has settled), or when `may_continue` says the frame's time is up (it
  // is asked before each iteration: a frame with no time left does none).
  Result correct(std::span<DeformationEngine* const> engines, std::span<const std::uint8_t> stepped,
                 int iterations, double relative_tolerance,
                 const std::function<bool()>& may_continue, hal::JobSystem* jobs);

 private:
  struct Sub {
    std::vector<int> grid_node;  // per local node
    // Whether the engine multiplies with its own tangent (tangent_stiffness_times); if not, its
    // rest stiffness in node blocks (its products stream half the bytes), one band: a
    // sub-volume's product is one task of the job system.
    bool own_tangent = false;
    detail::NodeBlockMatrix stiffness;
    Eigen::VectorXd spill;                // of the one band: empty
    Eigen::VectorXd local_in, local_out;  // 3 × local nodes: scratch
  };
  struct Copy {
    int sub = 0;
    int local = 0;
  };
  // q = D K D p over the stepped sub-volumes (`engines`: correct()'s).
  void multiply(std::span<DeformationEngine* const> engines, const Eigen::VectorXd& p,
                Eigen::VectorXd& q, hal::JobSystem* jobs);
  // out = Σ over each grid node's copies of the sub-volumes' local_out (free_only: over the free
  // nodes, 0 elsewhere).
  void gather(Eigen::VectorXd& out, bool free_only) const;

  static constexpr std::uint8_t kHeld = 0, kFree = 1, kSliding = 2;
  // Two copies of a node slide together if their normals are this close (under 1°).
  static constexpr double kSameNormalCosine = 0.99985;

  std::vector<Sub> subs_;
  std::vector<int> copies_begin_;  // per grid node, its copies (CSR)
  std::vector<Copy> copies_;
  std::vector<std::uint8_t> fixed_;
  Eigen::VectorXd inverse_diagonal_;  // of the summed stiffness, per grid DOF
  // Per frame, sized once.
  std::vector<std::uint8_t> free_;     // kHeld, kFree or kSliding
  SlidingNodes sliding_;               // the kSliding grid nodes
  std::vector<std::uint8_t> stepped_;  // per sub-volume
  std::vector<int> stepped_list_;
  Eigen::VectorXd x_, r_, z_, p_, q_;
};

}  // namespace ultrasim::sim
