#pragma once

// The explicit MSDS's springs laid out for SIMD (internal to MsdsEngine): every spring's elastic
// and damping force in single precision, summed per node.
//
// Layout. A spring (a, b), a < b, lies on the "diagonal" b − a, as in the DIA sparse format. On a
// grid mesh every spring lies on a handful of diagonals (9 for the 5-tet grid: 3 axes and 6 face
// diagonals), and along one diagonal the springs of consecutive nodes a read consecutive
// positions at a and a + offset: the kernels (msds_kernels.hpp) stream them with plain SIMD loads,
// no gathers. A diagonal keeps one slot per node a (stiffness 0 where there is no spring): a face
// diagonal is about half full, still far cheaper than gathering. Springs on sparse diagonals (a
// mesh that is not a grid) are "loose": each of their two nodes computes them, through a CSR list.
//
// Sums. The force on node i is Σ over diagonals, in offset order, of (slot i's force − slot
// (i − offset)'s force), then its loose springs in spring order: the same order whatever range or
// block the node is computed in, so a sweep split over tasks gives bitwise the same forces.
//
// Precision. Positions and velocities are read as float (the engine keeps its state in double and
// mirrors it); a spring's force is computed and summed in float. Rest lengths are the kernels'
// own float lengths of the rest positions (the same operations; the build does not contract them
// to FMA), so a mesh at rest is exactly in equilibrium, not in rounding noise.

#include <Eigen/Core>
#include <span>
#include <vector>

#include "msds_kernels.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim::msds_detail {

// A diagonal is kept dense when at least this fraction of its slots hold a spring: below it,
// computing each of its springs twice, one by one, is cheaper than its empty slots.
inline constexpr double kMinDiagonalFill = 0.25;

// The offsets b − a of the diagonals kept dense (at least kMinDiagonalFill of their
// node_count − offset slots hold a spring), increasing: where the explicit lattice and the
// implicit one (msds_implicit_lattice.hpp) lay their springs out; the others' springs are loose.
std::vector<int> dense_diagonal_offsets(std::span<const MsdsSpring> springs, int node_count);

class SpringLattice {
 public:
  // rest_positions_mm: the nodes at rest; springs: a < b, stiffness > 0; damping force =
  // stiffness × damping_per_stiffness_s × the relative velocity along the spring. Allocates.
  SpringLattice(std::span<const Eigen::Vector3d> rest_positions_mm,
                std::span<const MsdsSpring> springs, double damping_per_stiffness_s,
                const SpringKernels& kernels = fastest_kernels());

  // One task's scratch for sweeping the nodes [begin, end): each diagonal's slot forces from
  // begin − offset (the halo its first nodes need) to end. Allocates; one per concurrent task.
  class Sweep {
   public:
    Sweep() = default;
    Sweep(Sweep&&) = default;
    Sweep& operator=(Sweep&&) = default;
    Sweep(const Sweep&) = delete;  // `slots_` points into its own buffers
    Sweep& operator=(const Sweep&) = delete;

    int begin() const { return begin_; }
    int end() const { return end_; }

   private:
    friend class SpringLattice;
    int begin_ = 0;
    int end_ = 0;
    std::vector<std::vector<float>> buffers_;  // per diagonal: x, y, z forces, by slot
    std::vector<DiagonalSlots> slots_;
  };

  Sweep make_sweep(int begin, int end) const;
  // Computes the halo slots of a sweep from `state`: once per step, before its blocks.
  void start_sweep(Sweep& sweep, const FloatNodeState& state) const;
  // The spring + damping force (mN) on every node of [block_begin, block_end), a block of the
  // sweep's range, into f_*[node − block_begin] (each holding block size + kNodePadding). Blocks
  // go in increasing order: a block reads the slot forces of the blocks before it.
  void block_forces(Sweep& sweep, const FloatNodeState& state, int block_begin, int block_end,
                    float* f_x, float* f_y, float* f_z) const;

  const SpringKernels& kernels() const { return kernels_; }
  int diagonal_count() const { return static_cast<int>(diagonals_.size()); }
  int loose_spring_count() const { return static_cast<int>(loose_other_.size()) / 2; }

 private:
  // Springs (a, a + offset) for a in [0, node_count − offset); stiffness 0 in empty slots.
  struct Diagonal {
    int offset = 0;
    int slot_count = 0;
    std::vector<float> stiffness;    // mN/mm, slot_count + kNodePadding (zero past the end)
    std::vector<float> rest_length;  // mm
  };

  void build_diagonals(std::span<const MsdsSpring> springs);
  void build_loose_springs(std::span<const MsdsSpring> springs);
  // Slot forces of diagonal d for slots [first, last), collapsed springs included.
  void compute_slots(int d, DiagonalSlots& slots, const FloatNodeState& state, int first,
                     int last) const;
  // The force of one spring on node `from`, one by one: for loose springs and for the collapsed
  // ones the kernels leave out (pushed apart along their rest direction).
  Eigen::Vector3f spring_force_on(int from, int to, float stiffness, float rest_length,
                                  const FloatNodeState& state) const;
  void add_loose_forces(const FloatNodeState& state, int block_begin, int block_end, float* f_x,
                        float* f_y, float* f_z) const;

  SpringKernels kernels_;
  int node_count_ = 0;
  float damping_per_stiffness_s_ = 0.0f;
  FloatNodeState rest_;  // rest positions (zero velocity), for rest lengths and directions
  std::vector<Diagonal> diagonals_;
  // Loose springs, per node (CSR): the other node, stiffness and rest length, in spring order.
  std::vector<int> loose_begin_;
  std::vector<int> loose_other_;
  std::vector<float> loose_stiffness_;
  std::vector<float> loose_rest_length_;
};

}  // namespace ultrasim::sim::msds_detail
