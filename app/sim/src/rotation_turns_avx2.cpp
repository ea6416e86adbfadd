// The AVX2 turn kernel (rotation_turns.hpp): the portable kernel's arithmetic, operation for
// operation, on four tets at a time. Compiled for AVX2 per function (the build targets baseline
// x86-64) and used only where the CPU has it. Without FMA: the same roundings as the portable
// kernel.

#include <algorithm>
#include <cmath>
#include <limits>

#include "rotation_turns.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace ultrasim::sim::corotational_detail {

#if defined(__x86_64__)

namespace {

constexpr int kLanes = 4;

#define ULTRASIM_AVX2_INLINE [[gnu::target("avx2"), gnu::always_inline]] inline

// One double of each lane's tet: at[lane][offset].
ULTRASIM_AVX2_INLINE __m256d lanes(const double* const* at, int offset) {
  return _mm256_setr_pd(at[0][offset], at[1][offset], at[2][offset], at[3][offset]);
}

ULTRASIM_AVX2_INLINE __m256d add(__m256d a, __m256d b) {
  return _mm256_add_pd(a, b);
}
ULTRASIM_AVX2_INLINE __m256d sub(__m256d a, __m256d b) {
  return _mm256_sub_pd(a, b);
}
ULTRASIM_AVX2_INLINE __m256d mul(__m256d a, __m256d b) {
  return _mm256_mul_pd(a, b);
}
// !(a > b), true where either is NaN: the portable kernel's test.
ULTRASIM_AVX2_INLINE __m256d not_greater(__m256d a, __m256d b) {
  return _mm256_cmp_pd(a, b, _CMP_NGT_UQ);
}

// The turns of tets[0..3] into turns[tets[lane]].
[[gnu::target("avx2")]] void four_turns(const TurnInputs& in, const int* tets, double* turns) {
  const auto* rest = reinterpret_cast<const double*>(in.rest_mm);
  const double* g[kLanes];
  const double* r[kLanes];
  for (int lane = 0; lane < kLanes; ++lane) {
    g[lane] = in.shape_gradients[tets[lane]].data();
    r[lane] = in.rotations[tets[lane]].data();
  }
  __m256d x[4][3];
  for (int a = 0; a < 4; ++a) {
    const double* rest_at[kLanes];
    const double* u_at[kLanes];
    for (int lane = 0; lane < kLanes; ++lane) {
      const int node = in.tets[tets[lane]][a];
      rest_at[lane] = rest + 3 * node;
      u_at[lane] = in.u_mm + 3 * node;
    }
    for (int i = 0; i < 3; ++i) x[a][i] = add(lanes(rest_at, i), lanes(u_at, i));
  }
  __m256d gb[3][3];  // gb[b − 1][j]: node b's gradient
  for (int b = 1; b < 4; ++b) {
    for (int j = 0; j < 3; ++j) gb[b - 1][j] = lanes(g, 3 * b + j);
  }
  __m256d f[3][3];
  for (int i = 0; i < 3; ++i) {
    const __m256d e1 = sub(x[1][i], x[0][i]), e2 = sub(x[2][i], x[0][i]),
                  e3 = sub(x[3][i], x[0][i]);
    for (int j = 0; j < 3; ++j) {
      f[i][j] = add(add(mul(e1, gb[0][j]), mul(e2, gb[1][j])), mul(e3, gb[2][j]));
    }
  }
  __m256d s[3][3];
  for (int i = 0; i < 3; ++i) {
    const __m256d r0 = lanes(r, 3 * i), r1 = lanes(r, 3 * i + 1), r2 = lanes(r, 3 * i + 2);
    for (int j = 0; j < 3; ++j) {
      s[i][j] = add(add(mul(r0, f[0][j]), mul(r1, f[1][j])), mul(r2, f[2][j]));
    }
  }
  const __m256d half = _mm256_set1_pd(0.5);
  const __m256d d0 = s[0][0], d1 = s[1][1], d2 = s[2][2];
  const __m256d m01 = mul(half, add(s[0][1], s[1][0])), m02 = mul(half, add(s[0][2], s[2][0])),
                m12 = mul(half, add(s[1][2], s[2][1]));
  const __m256d minor2 = sub(mul(d0, d1), mul(m01, m01));
  const __m256d det_symmetric =
      add(sub(mul(d0, sub(mul(d1, d2), mul(m12, m12))), mul(m01, sub(mul(m01, d2), mul(m12, m02)))),
          mul(m02, sub(mul(m01, m12), mul(d1, m02))));
  const __m256d det_f = add(sub(mul(f[0][0], sub(mul(f[1][1], f[2][2]), mul(f[1][2], f[2][1]))),
                                mul(f[0][1], sub(mul(f[1][0], f[2][2]), mul(f[1][2], f[2][0])))),
                            mul(f[0][2], sub(mul(f[1][0], f[2][1]), mul(f[1][1], f[2][0]))));
  const __m256d collapsed = _mm256_set1_pd(kCollapsedStretch), zero = _mm256_setzero_pd();
  const __m256d lost = _mm256_or_pd(
      _mm256_or_pd(_mm256_or_pd(not_greater(d0, collapsed), not_greater(d1, collapsed)),
                   _mm256_or_pd(not_greater(d2, collapsed), not_greater(minor2, zero))),
      _mm256_or_pd(not_greater(det_symmetric, zero), not_greater(det_f, zero)));
  const __m256d t0 = _mm256_div_pd(sub(s[2][1], s[1][2]), add(d1, d2));
  const __m256d t1 = _mm256_div_pd(sub(s[0][2], s[2][0]), add(d0, d2));
  const __m256d t2 = _mm256_div_pd(sub(s[1][0], s[0][1]), add(d0, d1));
  const __m256d turn = _mm256_sqrt_pd(add(add(mul(t0, t0), mul(t1, t1)), mul(t2, t2)));
  alignas(32) double out[kLanes];
  _mm256_store_pd(
      out, _mm256_blendv_pd(turn, _mm256_set1_pd(std::numeric_limits<double>::infinity()), lost));
  for (int lane = 0; lane < kLanes; ++lane) turns[tets[lane]] = out[lane];
}

[[gnu::target("avx2")]] void avx2_turns(const TurnInputs& in, std::span<const int> tets,
                                        double* turns) {
  const auto count = static_cast<int>(tets.size());
  int i = 0;
  for (; i + kLanes <= count; i += kLanes) four_turns(in, tets.data() + i, turns);
  if (i < count) {
    // The last one to three, the lanes past them repeating the last tet (its turn written again).
    int last[kLanes];
    for (int lane = 0; lane < kLanes; ++lane) last[lane] = tets[std::min(i + lane, count - 1)];
    four_turns(in, last, turns);
  }
}

}  // namespace

TurnKernel fastest_turn_kernel() {
  if (__builtin_cpu_supports("avx2")) return &avx2_turns;
  return portable_turn_kernel();
}

#else

TurnKernel fastest_turn_kernel() {
  return portable_turn_kernel();
}

#endif

}  // namespace ultrasim::sim::corotational_detail
