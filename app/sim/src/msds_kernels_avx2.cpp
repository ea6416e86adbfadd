// The AVX2 kernels (msds_kernels.hpp): the portable kernels' arithmetic, operation for operation,
// on 8 floats or 4 doubles. Compiled for AVX2 per function (the build targets baseline x86-64)
// and used only where the CPU has it. Without FMA: the same roundings as the portable kernels.

#include <algorithm>
#include <cmath>
#include <limits>

#include "msds_kernels.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace ultrasim::sim::msds_detail {

#if defined(__x86_64__)

namespace {

constexpr int kFloatLanes = 8;
constexpr int kDoubleLanes = 4;
static_assert(kDoubleLanes == kEnergyLanes && kFloatLanes <= kNodePadding);

#define ULTRASIM_AVX2_INLINE [[gnu::target("avx2"), gnu::always_inline]] inline

// b − a of the nodes j.. and j + offset.. of one coordinate.
ULTRASIM_AVX2_INLINE __m256 difference(const float* a, int j, int offset) {
  return _mm256_sub_ps(_mm256_loadu_ps(a + j + offset), _mm256_loadu_ps(a + j));
}

ULTRASIM_AVX2_INLINE __m256 add(__m256 a, __m256 b) {
  return _mm256_add_ps(a, b);
}

ULTRASIM_AVX2_INLINE __m256 mul(__m256 a, __m256 b) {
  return _mm256_mul_ps(a, b);
}

[[gnu::target("avx2")]] bool slot_forces(const FloatNodeState& s, const DiagonalSlots& d,
                                         float damping_per_stiffness_s, int first, int last) {
  // Every pointer in a local: stores through float* could otherwise alias them, and the loop
  // would reload them each lane group.
  const int o = d.offset;
  const float *const x = s.x.data(), *const y = s.y.data(), *const z = s.z.data();
  const float *const vx = s.vx.data(), *const vy = s.vy.data(), *const vz = s.vz.data();
  const float *const stiffness = d.stiffness, *const rest_lengths = d.rest_length;
  float *const force_x = d.force_x, *const force_y = d.force_y, *const force_z = d.force_z;
  const int first_slot = d.first_slot;
  const __m256 collapsed_fraction = _mm256_set1_ps(kCollapsedFraction);
  const __m256 damping = _mm256_set1_ps(damping_per_stiffness_s);
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 zero = _mm256_setzero_ps();
  __m256 collapsed = zero;
  for (int j = first; j < last; j += kFloatLanes) {
    const __m256 dx = difference(x, j, o);
    const __m256 dy = difference(y, j, o);
    const __m256 dz = difference(z, j, o);
    const __m256 length = _mm256_sqrt_ps(add(add(mul(dx, dx), mul(dy, dy)), mul(dz, dz)));
    const __m256 k = _mm256_loadu_ps(stiffness + j);
    const __m256 rest_length = _mm256_loadu_ps(rest_lengths + j);
    const __m256 regular = _mm256_cmp_ps(length, mul(collapsed_fraction, rest_length), _CMP_GT_OQ);
    collapsed =
        _mm256_or_ps(collapsed, _mm256_andnot_ps(regular, _mm256_cmp_ps(k, zero, _CMP_GT_OQ)));
    const __m256 inverse_length = _mm256_and_ps(regular, _mm256_div_ps(one, length));
    const __m256 ux = mul(dx, inverse_length);
    const __m256 uy = mul(dy, inverse_length);
    const __m256 uz = mul(dz, inverse_length);
    const __m256 relative_speed =
        add(add(mul(difference(vx, j, o), ux), mul(difference(vy, j, o), uy)),
            mul(difference(vz, j, o), uz));
    const __m256 magnitude =
        add(mul(k, _mm256_sub_ps(length, rest_length)), mul(mul(k, damping), relative_speed));
    _mm256_storeu_ps(force_x + (j - first_slot), mul(magnitude, ux));
    _mm256_storeu_ps(force_y + (j - first_slot), mul(magnitude, uy));
    _mm256_storeu_ps(force_z + (j - first_slot), mul(magnitude, uz));
  }
  return _mm256_movemask_ps(collapsed) != 0;
}

ULTRASIM_AVX2_INLINE __m256 slot_difference(const float* force, int as_a, int as_b) {
  return _mm256_sub_ps(_mm256_loadu_ps(force + as_a), _mm256_loadu_ps(force + as_b));
}

[[gnu::target("avx2")]] void node_sums(std::span<const DiagonalSlots> diagonals, int begin, int end,
                                       float* f_x, float* f_y, float* f_z) {
  // Diagonal by diagonal into the sums (each diagonal's pointers loaded once), from +0.
  const int count = end - begin;
  for (int i = 0; i < count; i += kFloatLanes) {
    _mm256_storeu_ps(f_x + i, _mm256_setzero_ps());
    _mm256_storeu_ps(f_y + i, _mm256_setzero_ps());
    _mm256_storeu_ps(f_z + i, _mm256_setzero_ps());
  }
  for (const DiagonalSlots& d : diagonals) {
    const float *const force_x = d.force_x, *const force_y = d.force_y, *const force_z = d.force_z;
    const int as_a = begin - d.first_slot;  // node begin's slot as a, in the buffers
    const int as_b = as_a - d.offset;       // and as b
    for (int i = 0; i < count; i += kFloatLanes) {
      _mm256_storeu_ps(f_x + i,
                       add(_mm256_loadu_ps(f_x + i), slot_difference(force_x, as_a + i, as_b + i)));
      _mm256_storeu_ps(f_y + i,
                       add(_mm256_loadu_ps(f_y + i), slot_difference(force_y, as_a + i, as_b + i)));
      _mm256_storeu_ps(f_z + i,
                       add(_mm256_loadu_ps(f_z + i), slot_difference(force_z, as_a + i, as_b + i)));
    }
  }
}

// One coordinate of forward Euler on lanes i..; returns the new velocity.
ULTRASIM_AVX2_INLINE __m256d advance(double* x, double* v, const float* f, int i, int at,
                                     __m256d dt, __m256d step_per_force, float* next_x,
                                     float* next_v, __m256d& travel, __m256d& not_finite) {
  const __m256d x_old = _mm256_loadu_pd(x + i), v_old = _mm256_loadu_pd(v + i);
  const __m256d x_new = _mm256_add_pd(x_old, _mm256_mul_pd(dt, v_old));
  const __m256d v_new =
      _mm256_add_pd(v_old, _mm256_mul_pd(step_per_force, _mm256_cvtps_pd(_mm_loadu_ps(f + at))));
  travel = _mm256_add_pd(travel, _mm256_andnot_pd(_mm256_set1_pd(-0.0), v_old));  // |v|
  not_finite = _mm256_add_pd(not_finite, _mm256_sub_pd(x_new, x_new));
  _mm256_storeu_pd(x + i, x_new);
  _mm256_storeu_pd(v + i, v_new);
  _mm_storeu_ps(next_x + i, _mm256_cvtpd_ps(x_new));
  _mm_storeu_ps(next_v + i, _mm256_cvtpd_ps(v_new));
  return v_new;
}

[[gnu::target("avx2")]] NodeUpdateSums forward_euler(const ExplicitNodeArrays& n, int begin,
                                                     int end, double dt_s, const float* f_x,
                                                     const float* f_y, const float* f_z,
                                                     FloatNodeState& next) {
  double *const x = n.x, *const y = n.y, *const z = n.z;  // locals: see slot_forces
  double *const vx = n.vx, *const vy = n.vy, *const vz = n.vz;
  const double *const mass = n.mass_kg, *const inverse_mass = n.inverse_mass_per_kg;
  double* const probe_clearance = n.probe_clearance_mm;
  float *const next_x = next.x.data(), *const next_y = next.y.data(), *const next_z = next.z.data();
  float *const next_vx = next.vx.data(), *const next_vy = next.vy.data(),
               *const next_vz = next.vz.data();
  const __m256d dt = _mm256_set1_pd(dt_s);
  const __m256d half = _mm256_set1_pd(0.5);
  __m256d kinetic = _mm256_setzero_pd();
  __m256d not_finite = _mm256_setzero_pd();
  __m256d min_clearance = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  for (int i = begin; i < end; i += kDoubleLanes) {
    const __m256d step_per_force = _mm256_mul_pd(dt, _mm256_loadu_pd(inverse_mass + i));
    const int at = i - begin;
    __m256d travel = _mm256_setzero_pd();
    const __m256d new_vx =
        advance(x, vx, f_x, i, at, dt, step_per_force, next_x, next_vx, travel, not_finite);
    const __m256d new_vy =
        advance(y, vy, f_y, i, at, dt, step_per_force, next_y, next_vy, travel, not_finite);
    const __m256d new_vz =
        advance(z, vz, f_z, i, at, dt, step_per_force, next_z, next_vz, travel, not_finite);
    const __m256d clearance =
        _mm256_sub_pd(_mm256_loadu_pd(probe_clearance + i), _mm256_mul_pd(dt, travel));
    _mm256_storeu_pd(probe_clearance + i, clearance);
    min_clearance = _mm256_min_pd(min_clearance, clearance);
    const __m256d speed_squared =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(new_vx, new_vx), _mm256_mul_pd(new_vy, new_vy)),
                      _mm256_mul_pd(new_vz, new_vz));
    kinetic = _mm256_add_pd(
        kinetic, _mm256_mul_pd(_mm256_mul_pd(half, _mm256_loadu_pd(mass + i)), speed_squared));
  }
  alignas(32) double k[kDoubleLanes], c[kDoubleLanes];
  _mm256_store_pd(k, kinetic);
  _mm256_store_pd(c, min_clearance);
  NodeUpdateSums sums;
  sums.kinetic_energy_uj = (k[0] + k[1]) + (k[2] + k[3]);
  const int finite_lanes =
      _mm256_movemask_pd(_mm256_cmp_pd(not_finite, _mm256_setzero_pd(), _CMP_EQ_OQ));
  sums.finite = finite_lanes == (1 << kDoubleLanes) - 1 && std::isfinite(sums.kinetic_energy_uj);
  sums.min_probe_clearance_mm = std::min(std::min(c[0], c[1]), std::min(c[2], c[3]));
  return sums;
}

#undef ULTRASIM_AVX2_INLINE

}  // namespace

SpringKernels fastest_kernels() {
  if (__builtin_cpu_supports("avx2")) return {&slot_forces, &node_sums, &forward_euler};
  return portable_kernels();
}

#else

SpringKernels fastest_kernels() {
  return portable_kernels();
}

#endif

}  // namespace ultrasim::sim::msds_detail
