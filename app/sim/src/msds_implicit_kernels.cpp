// The implicit MSDS's diagonal loops (msds_implicit_kernels.hpp), written once and compiled for
// the baseline ISA and for AVX2 (per function: the build targets baseline x86-64). This file is
// compiled with the vectoriser's dynamic cost model, without errno for sqrt and without
// trapping maths (app/sim/CMakeLists.txt), so that the loops vectorise; none changes a result.
// Every loop reads and writes distinct arrays (`ivdep`: GCC would otherwise check the pointers for
// overlap at run time, more pairs than it will check, and leave the loop scalar).

#include "msds_implicit_kernels.hpp"

#include <cmath>
#include <cstdint>

namespace ultrasim::sim::msds_detail {

namespace {

#define ULTRASIM_KERNEL_BODY [[gnu::always_inline]] inline

ULTRASIM_KERNEL_BODY bool springs_body(NodeArrays position, const ImplicitSlots& s, double h,
                                       int first, int last) {
  const int o = s.offset;
  const double* x = position.x;
  const double* y = position.y;
  const double* z = position.z;
  const double* stiffness = s.stiffness;
  const double* damping = s.damping;
  const double* rest_length = s.rest_length;
  double* dir_x = s.dir_x;
  double* dir_y = s.dir_y;
  double* dir_z = s.dir_z;
  double* elastic = s.elastic;
  double* along = s.along;
  double* across = s.across;
  const double h2 = h * h;
  int collapsed = 0;
#pragma GCC ivdep
  for (int j = first; j < last; ++j) {
    const double dx = x[j + o] - x[j];
    const double dy = y[j + o] - y[j];
    const double dz = z[j + o] - z[j];
    const double length = std::sqrt((dx * dx + dy * dy) + dz * dz);
    const double k = stiffness[j];
    const double rest = rest_length[j];
    // Not `>`'s negation: a NaN length is collapsed too. An empty slot (k = 0) of two coincident
    // nodes gets a zero direction, not 0/0.
    const bool regular = length > kImplicitCollapsedFraction * rest;
    collapsed |= static_cast<int>(!regular) & static_cast<int>(k > 0.0);
    const double inverse_length = 1.0 / length;
    const double inverse = regular ? inverse_length : 0.0;
    const double nx = dx * inverse;
    const double ny = dy * inverse;
    const double nz = dz * inverse;
    const double stretched = 1.0 - rest * inverse;
    const double transverse = stretched > 0.0 ? stretched : 0.0;
    const double kh = h2 * k;
    dir_x[j] = nx;
    dir_y[j] = ny;
    dir_z[j] = nz;
    elastic[j] = k * (length - rest);
    along[j] = h * damping[j] + kh * (1.0 - transverse);
    across[j] = kh * transverse;
  }
  return collapsed != 0;
}

ULTRASIM_KERNEL_BODY void node_sums_body(const ImplicitSlots* diagonals, int count, int begin,
                                         int end, MutableNodeArrays elastic,
                                         MutableNodeArrays block_diagonal) {
  // A few nodes at a time, every diagonal summed into registers before one store (a pass per
  // diagonal read and wrote the sums' arrays per node each time).
  constexpr int kLanes = kImplicitSumLanes;
  for (int i0 = begin; i0 < end; i0 += kLanes) {
    double ex[kLanes] = {}, ey[kLanes] = {}, ez[kLanes] = {};
    double bx[kLanes] = {}, by[kLanes] = {}, bz[kLanes] = {};
    for (int d = 0; d < count; ++d) {
      const ImplicitSlots& s = diagonals[d];
      // Node i is slot i's a and slot (i − offset)'s b; slots outside the diagonal are zero.
      const double* dir_x = s.dir_x + i0;
      const double* dir_y = s.dir_y + i0;
      const double* dir_z = s.dir_z + i0;
      const double* f = s.elastic + i0;
      const double* along = s.along + i0;
      const double* across = s.across + i0;
      const int o = s.offset;
      for (int l = 0; l < kLanes; ++l) {
        ex[l] += f[l] * dir_x[l];
        ey[l] += f[l] * dir_y[l];
        ez[l] += f[l] * dir_z[l];
        bx[l] += along[l] * (dir_x[l] * dir_x[l]) + across[l];
        by[l] += along[l] * (dir_y[l] * dir_y[l]) + across[l];
        bz[l] += along[l] * (dir_z[l] * dir_z[l]) + across[l];
        const int j = l - o;
        ex[l] -= f[j] * dir_x[j];
        ey[l] -= f[j] * dir_y[j];
        ez[l] -= f[j] * dir_z[j];
        bx[l] += along[j] * (dir_x[j] * dir_x[j]) + across[j];
        by[l] += along[j] * (dir_y[j] * dir_y[j]) + across[j];
        bz[l] += along[j] * (dir_z[j] * dir_z[j]) + across[j];
      }
    }
    for (int l = 0; l < kLanes; ++l) {
      elastic.x[i0 + l] = ex[l];
      elastic.y[i0 + l] = ey[l];
      elastic.z[i0 + l] = ez[l];
      block_diagonal.x[i0 + l] = bx[l];
      block_diagonal.y[i0 + l] = by[l];
      block_diagonal.z[i0 + l] = bz[l];
    }
  }
}

ULTRASIM_KERNEL_BODY void multiply_body(const ImplicitSlots& s, int slot_count, NodeArrays p,
                                        int begin, int end, MutableNodeArrays product,
                                        MutableNodeArrays q) {
  const int o = s.offset;
  const double* px = p.x;
  const double* py = p.y;
  const double* pz = p.z;
  const double* dir_x = s.dir_x;
  const double* dir_y = s.dir_y;
  const double* dir_z = s.dir_z;
  const double* along = s.along;
  const double* across = s.across;
  // Slot j's product at [j − first].
  const int first = begin > o ? begin - o : 0;
  const int last = end < slot_count ? end : slot_count;
  double* gx = product.x - first;
  double* gy = product.y - first;
  double* gz = product.z - first;
#pragma GCC ivdep
  for (int j = first; j < last; ++j) {
    const double dx = px[j] - px[j + o];
    const double dy = py[j] - py[j + o];
    const double dz = pz[j] - pz[j + o];
    const double projected = along[j] * ((dir_x[j] * dx + dir_y[j] * dy) + dir_z[j] * dz);
    gx[j] = projected * dir_x[j] + across[j] * dx;
    gy[j] = projected * dir_y[j] + across[j] * dy;
    gz[j] = projected * dir_z[j] + across[j] * dz;
  }
  double* qx = q.x;
  double* qy = q.y;
  double* qz = q.z;
#pragma GCC ivdep
  for (int i = begin; i < last; ++i) {
    qx[i] += gx[i];
    qy[i] += gy[i];
    qz[i] += gz[i];
  }
#pragma GCC ivdep
  for (int i = begin > o ? begin : o; i < end; ++i) {
    qx[i] -= gx[i - o];
    qy[i] -= gy[i - o];
    qz[i] -= gz[i - o];
  }
}

// One coordinate of start_rows; the start's product read only when it is not zero (a load
// under a condition would keep the loop scalar).
template <bool kFromZero>
ULTRASIM_KERNEL_BODY void start_rows_axis(const StartRows& s, int axis, int begin, int end) {
  const auto pick = [axis](auto x, auto y, auto z) { return axis == 0 ? x : axis == 1 ? y : z; };
  const std::uint8_t* pinned = s.pinned;
  const std::uint8_t* held = s.held;
  const double* mass = s.mass_kg;
  const double* diagonal = s.system_diagonal;
  const double h = s.h;
  const double* block = pick(s.block_diagonal.x, s.block_diagonal.y, s.block_diagonal.z);
  const double* v = pick(s.velocity.x, s.velocity.y, s.velocity.z);
  const double* f = pick(s.elastic.x, s.elastic.y, s.elastic.z);
  const double* product = pick(s.start_product.x, s.start_product.y, s.start_product.z);
  double* inverse = pick(s.inverse_diagonal.x, s.inverse_diagonal.y, s.inverse_diagonal.z);
  double* rhs = pick(s.rhs.x, s.rhs.y, s.rhs.z);
  double* r = pick(s.r.x, s.r.y, s.r.z);
  double* z = pick(s.z.x, s.z.y, s.z.z);
  double* p = pick(s.p.x, s.p.y, s.p.z);
#pragma GCC ivdep
  for (int i = begin; i < end; ++i) {
    const bool moves = (pinned[i] | held[i]) == 0;
    const double d = 1.0 / (diagonal[i] + block[i]);
    const double b = mass[i] * v[i] + h * f[i];
    double start = b;
    if constexpr (!kFromZero) start = b - product[i];
    inverse[i] = moves ? d : 0.0;
    rhs[i] = moves ? b : 0.0;
    r[i] = moves ? start : 0.0;
    z[i] = moves ? d * start : 0.0;
    p[i] = z[i];
  }
}

ULTRASIM_KERNEL_BODY void start_rows_body(const StartRows& s, int begin, int end) {
  for (int axis = 0; axis < 3; ++axis) {
    if (s.start_product.x == nullptr) {
      start_rows_axis<true>(s, axis, begin, end);
    } else {
      start_rows_axis<false>(s, axis, begin, end);
    }
  }
}

ULTRASIM_KERNEL_BODY void cg_update_body(const CgVectors& cg, double alpha, int begin, int end) {
  for (int axis = 0; axis < 3; ++axis) {
    const auto pick = [axis](auto x, auto y, auto z) { return axis == 0 ? x : axis == 1 ? y : z; };
    double* v = pick(cg.velocity.x, cg.velocity.y, cg.velocity.z);
    double* r = pick(cg.r.x, cg.r.y, cg.r.z);
    double* z = pick(cg.z.x, cg.z.y, cg.z.z);
    const double* p = pick(cg.p.x, cg.p.y, cg.p.z);
    const double* q = pick(cg.q.x, cg.q.y, cg.q.z);
    const double* d = pick(cg.inverse_diagonal.x, cg.inverse_diagonal.y, cg.inverse_diagonal.z);
#pragma GCC ivdep
    for (int i = begin; i < end; ++i) {
      v[i] += alpha * p[i];
      r[i] -= alpha * q[i];
      z[i] = d[i] * r[i];
    }
  }
}

ULTRASIM_KERNEL_BODY void cg_direction_body(const CgVectors& cg, double beta, int begin, int end) {
  for (int axis = 0; axis < 3; ++axis) {
    const auto pick = [axis](auto x, auto y, auto z) { return axis == 0 ? x : axis == 1 ? y : z; };
    double* p = pick(cg.p.x, cg.p.y, cg.p.z);
    const double* z = pick(cg.z.x, cg.z.y, cg.z.z);
#pragma GCC ivdep
    for (int i = begin; i < end; ++i) p[i] = z[i] + beta * p[i];
  }
}

bool springs_portable(NodeArrays position, const ImplicitSlots& slots, double h, int first,
                      int last) {
  return springs_body(position, slots, h, first, last);
}

void node_sums_portable(const ImplicitSlots* diagonals, int count, int begin, int end,
                        MutableNodeArrays elastic, MutableNodeArrays block_diagonal) {
  node_sums_body(diagonals, count, begin, end, elastic, block_diagonal);
}

void multiply_portable(const ImplicitSlots& slots, int slot_count, NodeArrays p, int begin, int end,
                       MutableNodeArrays product, MutableNodeArrays q) {
  multiply_body(slots, slot_count, p, begin, end, product, q);
}

void start_rows_portable(const StartRows& rows, int begin, int end) {
  start_rows_body(rows, begin, end);
}

void cg_update_portable(const CgVectors& cg, double alpha, int begin, int end) {
  cg_update_body(cg, alpha, begin, end);
}

void cg_direction_portable(const CgVectors& cg, double beta, int begin, int end) {
  cg_direction_body(cg, beta, begin, end);
}

#if defined(__x86_64__)

[[gnu::target("avx2")]] void start_rows_avx2(const StartRows& rows, int begin, int end) {
  start_rows_body(rows, begin, end);
}

[[gnu::target("avx2")]] void cg_update_avx2(const CgVectors& cg, double alpha, int begin, int end) {
  cg_update_body(cg, alpha, begin, end);
}

[[gnu::target("avx2")]] void cg_direction_avx2(const CgVectors& cg, double beta, int begin,
                                               int end) {
  cg_direction_body(cg, beta, begin, end);
}

[[gnu::target("avx2")]] bool springs_avx2(NodeArrays position, const ImplicitSlots& slots, double h,
                                          int first, int last) {
  return springs_body(position, slots, h, first, last);
}

[[gnu::target("avx2")]] void node_sums_avx2(const ImplicitSlots* diagonals, int count, int begin,
                                            int end, MutableNodeArrays elastic,
                                            MutableNodeArrays block_diagonal) {
  node_sums_body(diagonals, count, begin, end, elastic, block_diagonal);
}

[[gnu::target("avx2")]] void multiply_avx2(const ImplicitSlots& slots, int slot_count, NodeArrays p,
                                           int begin, int end, MutableNodeArrays product,
                                           MutableNodeArrays q) {
  multiply_body(slots, slot_count, p, begin, end, product, q);
}

#endif

#undef ULTRASIM_KERNEL_BODY

}  // namespace

ImplicitKernels portable_implicit_kernels() {
  return {&springs_portable, &node_sums_portable, &multiply_portable};
}

ImplicitKernels fastest_implicit_kernels() {
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2")) return {&springs_avx2, &node_sums_avx2, &multiply_avx2};
#endif
  return portable_implicit_kernels();
}

ImplicitVectorKernels portable_implicit_vector_kernels() {
  return {&start_rows_portable, &cg_update_portable, &cg_direction_portable};
}

ImplicitVectorKernels fastest_implicit_vector_kernels() {
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2")) {
    return {&start_rows_avx2, &cg_update_avx2, &cg_direction_avx2};
  }
#endif
  return portable_implicit_vector_kernels();
}

}  // namespace ultrasim::sim::msds_detail
