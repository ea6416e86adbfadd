#pragma once

// The implicit MSDS's loops over one diagonal of its spring lattice (internal to MsdsEngine,
// msds_implicit_lattice.hpp), in double: each spring's direction, forces and block of the
// system, their per-node sums, and the system's product. Plain loops over arrays, compiled twice
// from one source (msds_implicit_kernels.cpp): for the build's baseline ISA and, picked at run
// time where the CPU has it, for AVX2, both vectorised by the compiler. Element by element, with
// no FMA and no reassociation, the two do the same IEEE operations and give bitwise the same
// results (msds_implicit_lattice_test.cpp).

#include <cstdint>

namespace ultrasim::sim::msds_detail {

// One coordinate each, indexed by node.
struct NodeArrays {
  const double* x = nullptr;
  const double* y = nullptr;
  const double* z = nullptr;
};
struct MutableNodeArrays {
  double* x = nullptr;
  double* y = nullptr;
  double* z = nullptr;
};

// The springs (j, j + offset) of one diagonal, slot j, and what the spring pass leaves there:
// its unit vector from j to j + offset, its elastic force k (l − L) along it (on node j; node
// j + offset takes the opposite), and its block h c n nᵀ + h² k [n nᵀ + t (I − n nᵀ)] =
// along n nᵀ + across I, t = max(0, 1 − L / l) (the transverse term dropped for compressed
// springs). Empty slots have k = c = L = 0: zero forces and blocks. (The damping force is only
// wanted at held nodes, which compute it themselves.)
struct ImplicitSlots {
  int offset = 0;
  const double* stiffness = nullptr;    // mN/mm
  const double* damping = nullptr;      // mN·s/mm
  const double* rest_length = nullptr;  // mm
  double* dir_x = nullptr;
  double* dir_y = nullptr;
  double* dir_z = nullptr;
  double* elastic = nullptr;  // mN
  double* along = nullptr;    // kg
  double* across = nullptr;
};

// node_sums' nodes at a time.
inline constexpr int kImplicitSumLanes = 4;

// A spring shorter than this fraction of its rest length has no reliable direction of its own.
inline constexpr double kImplicitCollapsedFraction = 1e-9;

struct ImplicitKernels {
  // Slots [first, last) from the positions (mm), time step h (s). Returns whether a slot
  // holding a spring is collapsed (l ≤ kImplicitCollapsedFraction L, or not finite): its
  // direction is then the caller's to set.
  bool (*springs)(NodeArrays position, const ImplicitSlots& slots, double h, int first, int last);
  // For each node i of [begin, end) (rounded up to whole kImplicitSumLanes, from a multiple of
  // them): over the diagonals in order, + slot i's elastic force vector and its block's
  // diagonal, then − the force of slot i − offset, + its block's diagonal. Overwrites the
  // outputs. Reads the slots' state from −offset to node_count + kImplicitSumLanes, zero outside
  // the diagonal (its padding).
  void (*node_sums)(const ImplicitSlots* diagonals, int count, int begin, int end,
                    MutableNodeArrays elastic, MutableNodeArrays block_diagonal);
  // q_i += slot i's block × (p_i − p_{i+offset}) where i < slot_count, then −= slot (i −
  // offset)'s × (p_{i−offset} − p_i) where i ≥ offset, for i in [begin, end). `product` holds
  // the slots' products from max(0, begin − offset) on: scratch of end − begin + offset.
  void (*multiply)(const ImplicitSlots& slots, int slot_count, NodeArrays p, int begin, int end,
                   MutableNodeArrays product, MutableNodeArrays q);
};

// What the start of a step reads and writes, node by node (MsdsEngine::implicit_euler_update).
// A node moves unless pinned or held; the rows of those that do not are zero.
struct StartRows {
  const std::uint8_t* pinned = nullptr;
  const std::uint8_t* held = nullptr;
  const double* mass_kg = nullptr;
  const double* system_diagonal = nullptr;  // M + h² k_anchor, kg
  NodeArrays block_diagonal;                // the springs' blocks' diagonals, kg
  NodeArrays velocity;                      // v0, mm/s
  NodeArrays elastic;                       // springs' and anchor's elastic force, mN
  NodeArrays start_product;                 // A v_start, or x = nullptr for a zero start
  double h = 0.0;
  MutableNodeArrays inverse_diagonal, rhs, r, z, p;
};

// The CG's vectors (Jacobi-preconditioned, matrix-free).
struct CgVectors {
  MutableNodeArrays velocity, r, z, p;
  NodeArrays q, inverse_diagonal;
};

struct ImplicitVectorKernels {
  // For nodes [begin, end): the inverse of the system's diagonal, rhs = M v0 + h f_e,
  // r = rhs − A v_start (rhs from zero), z = p = the preconditioned r.
  void (*start_rows)(const StartRows& rows, int begin, int end);
  // v += α p, r −= α q, z = D⁻¹ r on nodes [begin, end).
  void (*cg_update)(const CgVectors& cg, double alpha, int begin, int end);
  // p = z + β p on nodes [begin, end).
  void (*cg_direction)(const CgVectors& cg, double beta, int begin, int end);
};

ImplicitKernels portable_implicit_kernels();
// The AVX2 build where the CPU has AVX2, else the portable one.
ImplicitKernels fastest_implicit_kernels();
ImplicitVectorKernels portable_implicit_vector_kernels();
ImplicitVectorKernels fastest_implicit_vector_kernels();

}  // namespace ultrasim::sim::msds_detail
