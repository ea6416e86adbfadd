#pragma once

// The explicit MSDS's SIMD kernels (internal to MsdsEngine): spring forces along one diagonal of
// the spring lattice, their per-node sums, and the forward Euler node update. Two
// implementations of the same arithmetic: a portable one (std::experimental::simd, the build's
// baseline ISA) and an AVX2 one (x86-64 intrinsics, picked at run time where the CPU has AVX2).
// Both do the same IEEE operations in the same order (no FMA contraction, correctly rounded
// sqrt and division), so they give bitwise the same results (msds_kernels_test.cpp).

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace ultrasim::sim::msds_detail {

// Slots past the last node that every per-node array of the kernels carries (zero, or a node
// that never moves): a SIMD lane group may read and write past the end. At least any SIMD width.
inline constexpr int kNodePadding = 64;

// The update sums the kinetic energy of nodes i with i mod kEnergyLanes apart, then the partial
// sums as (s0 + s1) + (s2 + s3): the same order in every implementation.
inline constexpr int kEnergyLanes = 4;

// A spring shorter than this fraction of its rest length has no reliable direction of its own.
inline constexpr float kCollapsedFraction = 1e-9f;

// Node positions (mm) and velocities (mm/s) in float, one array per coordinate, each
// node_count + kNodePadding long: what the spring kernel reads.
struct FloatNodeState {
  std::vector<float> x, y, z, vx, vy, vz;

  void assign_zero(int node_count);
  void set(int node, const Eigen::Vector3d& position_mm, const Eigen::Vector3d& velocity_mm_per_s);
};

// The springs (a, a + offset) of one diagonal, one slot per node a (stiffness 0 where there is
// no spring), and where their forces go.
struct DiagonalSlots {
  int offset = 0;
  const float* stiffness = nullptr;    // mN/mm, by slot
  const float* rest_length = nullptr;  // mm, by slot
  // Force on the slot's node a (mN); slot j at [j − first_slot].
  int first_slot = 0;
  float* force_x = nullptr;
  float* force_y = nullptr;
  float* force_z = nullptr;
};

// The engine's per-node arrays the update reads and writes, one array per coordinate, each
// kNodePadding past the last node.
struct ExplicitNodeArrays {
  double* x = nullptr;  // positions, mm (updated)
  double* y = nullptr;
  double* z = nullptr;
  double* vx = nullptr;  // velocities, mm/s (updated)
  double* vy = nullptr;
  double* vz = nullptr;
  const double* mass_kg = nullptr;
  // 0 where a node never moves (its velocity stays 0 and its position with it).
  const double* inverse_mass_per_kg = nullptr;
  // A lower bound of each node's distance to the probe's surface, lowered by how far the node
  // moves (the L1 norm of its step, ≥ its length), so a node whose bound stays above the contact
  // tolerance cannot have reached the probe.
  double* probe_clearance_mm = nullptr;
};

struct NodeUpdateSums {
  double kinetic_energy_uj = 0.0;
  bool finite = true;  // every new position and velocity
  // The smallest probe clearance bound of the nodes, after the update (exact: a minimum does not
  // round; a NaN, which only a non-finite state gives, may be left out).
  double min_probe_clearance_mm = 0.0;
};

struct SpringKernels {
  // Forces of the diagonal's slots [first, last) (rounded up to whole lane groups) from
  // `state`: elastic k (l − L) and damping β k (Δv · u) along the spring, u its unit vector.
  // Returns whether a slot holding a spring is collapsed (l ≤ kCollapsedFraction L): its force
  // is left 0, for the caller to compute along the rest direction.
  bool (*slot_forces)(const FloatNodeState& state, const DiagonalSlots& diagonal,
                      float damping_per_stiffness_s, int first, int last);
  // For each node i of [begin, end) (rounded up likewise): Σ over the diagonals, in order, of
  // slot i's force − slot (i − offset)'s force, into f_*[i − begin].
  void (*node_sums)(std::span<const DiagonalSlots> diagonals, int begin, int end, float* f_x,
                    float* f_y, float* f_z);
  // Forward Euler, as published, on nodes [begin, end) (rounded up likewise): x += dt v with the
  // old velocity, v += dt / m × f with the old state's force (f_*[i − begin], mN; 0 on nodes held
  // on the probe). Writes the new state to `next_state`.
  NodeUpdateSums (*forward_euler)(const ExplicitNodeArrays& nodes, int begin, int end, double dt_s,
                                  const float* f_x, const float* f_y, const float* f_z,
                                  FloatNodeState& next_state);
};

SpringKernels portable_kernels();
// The AVX2 kernels where the CPU has AVX2, else the portable ones. (AVX-512 was tried for the
// spring kernel: no faster in place on this 2-core Zen 4 target, so not kept.)
SpringKernels fastest_kernels();

}  // namespace ultrasim::sim::msds_detail
