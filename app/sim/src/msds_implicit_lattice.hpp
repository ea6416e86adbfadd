#pragma once

// The implicit MSDS's springs laid out by diagonal, in double (internal to MsdsEngine): each
// spring's forces and block of the system, their per-node sums, and the system's product.
//
// Layout. As the explicit step's (msds_spring_lattice.hpp): a spring (a, b), a < b, lies on the
// diagonal b − a; on a grid mesh every spring lies on a few diagonals, along which consecutive
// slots read consecutive nodes, so the loops (msds_implicit_kernels.hpp) stream arrays instead of
// gathering; springs on sparse diagonals (a mesh that is not a grid) are loose and go one by one.
// Each spring is computed once a step (and once a product), not once from each of its nodes.
//
// Order. A node's sums go over the diagonals in offset order (its own slot, then the slot offset
// below), then its loose springs in spring order: the same whatever range a node is computed in,
// so results do not depend on how the work is split among threads.

#include <Eigen/Core>
#include <span>
#include <vector>

#include "msds_implicit_kernels.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim::msds_detail {

class ImplicitLattice {
 public:
  // The springs' and products' work is split into ranges of this many nodes (a multiple of the
  // engine's node chunks): a range's product recomputes the slots below its first node, as few
  // as the largest offset, so ranges are long.
  static constexpr int kNodesPerRange = 4096;

  // springs: a < b, each with its rest length, stiffness and damping. Allocates.
  ImplicitLattice(std::span<const Eigen::Vector3d> rest_positions_mm,
                  std::span<const MsdsSpring> springs,
                  const ImplicitKernels& kernels = fastest_implicit_kernels(),
                  const ImplicitVectorKernels& vector_kernels = fastest_implicit_vector_kernels());
  // The slots point into the lattice's own arrays.
  ImplicitLattice(const ImplicitLattice&) = delete;
  ImplicitLattice& operator=(const ImplicitLattice&) = delete;

  int range_count() const;
  int range_begin(int range) const { return range * kNodesPerRange; }
  int range_end(int range) const;

  // Every spring whose node a lies in the range: its direction, elastic force and block at the
  // positions, time step h (s).
  void compute_springs(int range, NodeArrays position, double h);
  // For the nodes [begin, end): Σ ± of their springs' elastic forces (mN) and of their blocks'
  // diagonals (kg). Overwrites the outputs there, and up to the next multiple of
  // kImplicitSumLanes past end (begin a multiple of it; outputs padded). After compute_springs of
  // every range.
  void sum_node_forces(int begin, int end, MutableNodeArrays elastic,
                       MutableNodeArrays block_diagonal) const;
  // The springs' damping force on one node, c (Δv · n) n over its springs (mN), along the
  // directions compute_springs found. For the few nodes that want it (held on the probe).
  Eigen::Vector3d damping_force_on(int node, NodeArrays velocity) const;
  // q = diagonal ∘ p + Σ over each node's springs of their blocks × (p_node − p_other), on the
  // range's nodes (diagonal: one scalar per node, kg). After compute_springs of every range; one
  // call per range at a time.
  void multiply(int range, const double* diagonal, NodeArrays p, MutableNodeArrays q);

  // The step's node-by-node loops, from the same build as the lattice's.
  const ImplicitVectorKernels& vector_kernels() const { return vector_kernels_; }

  int diagonal_count() const { return static_cast<int>(diagonals_.size()); }
  int loose_spring_count() const { return static_cast<int>(loose_.size()); }

 private:
  // A spring's forces and block, in the slots' terms.
  struct SlotState {
    std::vector<double> dir_x, dir_y, dir_z, elastic, along, across;
  };
  struct Diagonal {
    int offset = 0;
    int slot_count = 0;
    std::vector<double> stiffness, damping, rest_length;  // zero in empty slots
    SlotState state;
    ImplicitSlots slots;  // points into the vectors above
  };
  struct LooseSpring {
    int a = 0;
    int b = 0;
    double stiffness = 0.0;
    double damping = 0.0;
    double rest_length = 0.0;
  };

  void build_diagonals(std::span<const MsdsSpring> springs);
  void build_loose_springs(std::span<const MsdsSpring> springs);
  // A collapsed spring's direction is its rest direction (pushed apart along it): the slots the
  // kernel flagged, one by one.
  void settle_collapsed(Diagonal& d, NodeArrays position, double h, int first, int last);
  // One spring's slot values, one by one: the kernel's arithmetic, the rest direction where it
  // is collapsed.
  void compute_one(int a, int b, double stiffness, double damping, double rest_length,
                   NodeArrays position, double h, double& dir_x, double& dir_y, double& dir_z,
                   double& elastic, double& along, double& across) const;

  ImplicitKernels kernels_;
  ImplicitVectorKernels vector_kernels_;
  int node_count_ = 0;
  std::vector<Eigen::Vector3d> rest_;
  std::vector<Diagonal> diagonals_;
  std::vector<ImplicitSlots> slots_;  // each diagonal's, in offset order
  int front_padding_ = 0;             // zero slots before each diagonal's first: the largest offset
  // Loose springs in spring order (by a), their state by the same index, where each range's
  // begin (by a), and per node (CSR) the loose springs it is in, with +1 as a and −1 as b.
  std::vector<LooseSpring> loose_;
  SlotState loose_state_;
  std::vector<int> loose_of_range_;
  std::vector<int> loose_begin_;
  std::vector<int> loose_index_;
  std::vector<double> loose_sign_;
  // Per range, the product's scratch: one slot product per coordinate.
  std::vector<std::vector<double>> product_scratch_;
};

}  // namespace ultrasim::sim::msds_detail
