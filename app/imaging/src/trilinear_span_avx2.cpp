// The AVX2 span kernels (trilinear_span.hpp): the portable kernels' arithmetic, operation for
// operation, on four pixels at a time. Compiled for AVX2 per function (the build targets baseline
// x86-64) and used only where the CPU has it. Without FMA: the same roundings as the portable
// kernels.

#include <algorithm>
#include <cmath>
#include <cstring>

#include "trilinear_span.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace ultrasim::imaging::slicer_detail {

#if defined(__x86_64__)

namespace {

constexpr int kLanes = 4;

#define ULTRASIM_AVX2_INLINE [[gnu::target("avx2"), gnu::always_inline]] inline

// a + (b − a) · f of each lane, with a and b the low and the high byte of each lane's 16-bit
// word (voxels i and i + 1 along x): the portable kernel's `p[0] + (p[1] − p[0]) · fx`, the byte
// difference taken in integers, then converted.
ULTRASIM_AVX2_INLINE __m256d lerp_x(__m128i words, __m256d f) {
  const __m128i byte = _mm_set1_epi32(0xFF);
  const __m128i a = _mm_and_si128(words, byte);
  const __m128i b = _mm_and_si128(_mm_srli_epi32(words, 8), byte);
  return _mm256_add_pd(_mm256_cvtepi32_pd(a),
                       _mm256_mul_pd(_mm256_cvtepi32_pd(_mm_sub_epi32(b, a)), f));
}

// The 16-bit words at voxels + offset of each lane, zero-extended: scalar loads, which this
// host's (AMD) gathers are slower than.
ULTRASIM_AVX2_INLINE __m128i pairs_at(const std::uint8_t* voxels, const int* offsets,
                                      std::ptrdiff_t shift) {
  const auto pair = [&](int lane) {
    std::uint16_t word;
    std::memcpy(&word, voxels + offsets[lane] + shift, sizeof word);
    return static_cast<int>(word);
  };
  return _mm_setr_epi32(pair(0), pair(1), pair(2), pair(3));
}

ULTRASIM_AVX2_INLINE __m256d lerp(__m256d a, __m256d b, __m256d f) {
  return _mm256_add_pd(a, _mm256_mul_pd(_mm256_sub_pd(b, a), f));
}

// What every group of four pixels of a span needs, broadcast to the lanes once per span.
struct SpanLanes {
  __m128i stride_y, stride_z, max_i, max_j, max_k;
  __m256d x0, y0, z0, dx, dy, dz;
};

ULTRASIM_AVX2_INLINE SpanLanes span_lanes(const VoxelGrid& g, const double* index_at_col0,
                                          const double* step) {
  return {_mm_set1_epi32(static_cast<int>(g.stride_y)),
          _mm_set1_epi32(static_cast<int>(g.stride_z)),
          _mm_set1_epi32(g.max_i),
          _mm_set1_epi32(g.max_j),
          _mm_set1_epi32(g.max_k),
          _mm256_set1_pd(index_at_col0[0]),
          _mm256_set1_pd(index_at_col0[1]),
          _mm256_set1_pd(index_at_col0[2]),
          _mm256_set1_pd(step[0]),
          _mm256_set1_pd(step[1]),
          _mm256_set1_pd(step[2])};
}

// The grey levels of the pixels at columns c (whole numbers), as four bytes, lane 0 lowest.
template <bool kClamp>
ULTRASIM_AVX2_INLINE int four_greys(const VoxelGrid& g, const SpanLanes& l, __m256d c) {
  const __m256d xi = _mm256_add_pd(l.x0, _mm256_mul_pd(c, l.dx));
  const __m256d yi = _mm256_add_pd(l.y0, _mm256_mul_pd(c, l.dy));
  const __m256d zi = _mm256_add_pd(l.z0, _mm256_mul_pd(c, l.dz));
  __m128i i = _mm256_cvttpd_epi32(xi), j = _mm256_cvttpd_epi32(yi), k = _mm256_cvttpd_epi32(zi);
  if constexpr (kClamp) {
    i = _mm_min_epi32(i, l.max_i);
    j = _mm_min_epi32(j, l.max_j);
    k = _mm_min_epi32(k, l.max_k);
  }
  const __m256d fx = _mm256_sub_pd(xi, _mm256_cvtepi32_pd(i));
  const __m256d fy = _mm256_sub_pd(yi, _mm256_cvtepi32_pd(j));
  const __m256d fz = _mm256_sub_pd(zi, _mm256_cvtepi32_pd(k));
  const __m128i p = _mm_add_epi32(
      i, _mm_add_epi32(_mm_mullo_epi32(j, l.stride_y), _mm_mullo_epi32(k, l.stride_z)));
  alignas(16) int offsets[kLanes];
  _mm_store_si128(reinterpret_cast<__m128i*>(offsets), p);
  const __m256d c00 = lerp_x(pairs_at(g.voxels, offsets, 0), fx);
  const __m256d c10 = lerp_x(pairs_at(g.voxels, offsets, g.step_y), fx);
  const __m256d c01 = lerp_x(pairs_at(g.voxels, offsets, g.step_z), fx);
  const __m256d c11 = lerp_x(pairs_at(g.voxels, offsets, g.step_y + g.step_z), fx);
  const __m256d c0 = lerp(c00, c10, fy);
  const __m256d c1 = lerp(c01, c11, fy);
  const __m256d grey = _mm256_min_pd(
      _mm256_max_pd(_mm256_add_pd(_mm256_add_pd(c0, _mm256_mul_pd(_mm256_sub_pd(c1, c0), fz)),
                                  _mm256_set1_pd(0.5)),
                    _mm256_setzero_pd()),
      _mm256_set1_pd(255.0));
  const __m128i levels = _mm256_cvttpd_epi32(grey);  // 0..255: the packs below keep them
  const __m128i bytes = _mm_packus_epi16(_mm_packus_epi32(levels, levels), _mm_setzero_si128());
  return _mm_cvtsi128_si32(bytes);
}

template <bool kClamp>
[[gnu::target("avx2")]] void sample_span(const VoxelGrid& g, const double* index_at_col0,
                                         const double* step, int first, int last,
                                         std::uint8_t* out) {
  if (last < first) return;
  // Each lane reads its voxels i and i + 1 along x as one 16-bit word: only with a second voxel
  // along x (the portable kernel reads voxel i twice without one).
  if (g.step_x != 1) {
    (kClamp ? portable_clamped_span : portable_inside_span)(g, index_at_col0, step, first, last,
                                                            out);
    return;
  }
  const SpanLanes l = span_lanes(g, index_at_col0, step);
  const __m256d lane = _mm256_setr_pd(0.0, 1.0, 2.0, 3.0);  // whole numbers: c is exact
  const int pixels = last - first + 1;
  if (pixels < kLanes) {
    // The lanes past the span repeat its last pixel (whose reads are in bounds); only the span's
    // own bytes are stored.
    const __m256d c =
        _mm256_min_pd(_mm256_add_pd(_mm256_set1_pd(first), lane), _mm256_set1_pd(last));
    const int four = four_greys<kClamp>(g, l, c);
    std::memcpy(out + first, &four, static_cast<std::size_t>(pixels));
    return;
  }
  // The last four pixels may overlap the group before them: a pixel's value depends only on its
  // column, so it is written twice with the same byte rather than left to a one-pixel loop.
  for (int group = first;; group += kLanes) {
    const int col = std::min(group, last - kLanes + 1);
    const int four = four_greys<kClamp>(g, l, _mm256_add_pd(_mm256_set1_pd(col), lane));
    std::memcpy(out + col, &four, sizeof four);
    if (col + kLanes > last) break;
  }
}

#undef ULTRASIM_AVX2_INLINE

}  // namespace

SpanKernels fastest_span_kernels() {
  if (__builtin_cpu_supports("avx2")) return {&sample_span<false>, &sample_span<true>};
  return portable_span_kernels();
}

#else

SpanKernels fastest_span_kernels() {
  return portable_span_kernels();
}

#endif

}  // namespace ultrasim::imaging::slicer_detail
