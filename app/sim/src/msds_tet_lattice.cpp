#include "msds_tet_lattice.hpp"

#include <algorithm>
#include <map>

#include "msds_kernels.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace ultrasim::sim::msds_detail {

namespace {

constexpr int kSlotsPerChunk = 2048;  // a multiple of the 4 lanes
constexpr int kLooseTetsPerChunk = 1024;

#if defined(__x86_64__)

// One coordinate of node k of the tets in slots m..m + 3.
[[gnu::target("avx2"), gnu::always_inline]] inline __m256d coordinate(const double* c, int m,
                                                                      int offset) {
  return _mm256_loadu_pd(c + m + offset);
}

// Tets in slots [first, last) of a pattern (first a multiple of 4) with a signed volume ≤ 0:
// six_signed_volume's operations on four slots at a time.
[[gnu::target("avx2,popcnt")]] int count_inverted_avx2(const std::array<int, 4>& o,
                                                       const std::uint8_t* occupied, int first,
                                                       int last, const double* x, const double* y,
                                                       const double* z) {
  int inverted = 0;
  for (int m = first; m < last; m += 4) {
    const __m256d x0 = coordinate(x, m, o[0]), y0 = coordinate(y, m, o[0]),
                  z0 = coordinate(z, m, o[0]);
    const __m256d ux = _mm256_sub_pd(coordinate(x, m, o[1]), x0);
    const __m256d uy = _mm256_sub_pd(coordinate(y, m, o[1]), y0);
    const __m256d uz = _mm256_sub_pd(coordinate(z, m, o[1]), z0);
    const __m256d vx = _mm256_sub_pd(coordinate(x, m, o[2]), x0);
    const __m256d vy = _mm256_sub_pd(coordinate(y, m, o[2]), y0);
    const __m256d vz = _mm256_sub_pd(coordinate(z, m, o[2]), z0);
    const __m256d wx = _mm256_sub_pd(coordinate(x, m, o[3]), x0);
    const __m256d wy = _mm256_sub_pd(coordinate(y, m, o[3]), y0);
    const __m256d wz = _mm256_sub_pd(coordinate(z, m, o[3]), z0);
    const __m256d cx = _mm256_sub_pd(_mm256_mul_pd(uy, vz), _mm256_mul_pd(uz, vy));
    const __m256d cy = _mm256_sub_pd(_mm256_mul_pd(uz, vx), _mm256_mul_pd(ux, vz));
    const __m256d cz = _mm256_sub_pd(_mm256_mul_pd(ux, vy), _mm256_mul_pd(uy, vx));
    const __m256d volume = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(cx, wx), _mm256_mul_pd(cy, wy)), _mm256_mul_pd(cz, wz));
    const int not_positive =
        _mm256_movemask_pd(_mm256_cmp_pd(volume, _mm256_setzero_pd(), _CMP_LE_OQ));
    inverted += __builtin_popcount(static_cast<unsigned>(not_positive & occupied[m / 4]));
  }
  return inverted;
}

bool cpu_has_avx2() {
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
}

#else

bool cpu_has_avx2() {
  return false;
}

#endif

}  // namespace

double six_signed_volume(const double* x, const double* y, const double* z,
                         const geometry::Tet& t) {
  const double ux = x[t[1]] - x[t[0]], uy = y[t[1]] - y[t[0]], uz = z[t[1]] - z[t[0]];
  const double vx = x[t[2]] - x[t[0]], vy = y[t[2]] - y[t[0]], vz = z[t[2]] - z[t[0]];
  const double wx = x[t[3]] - x[t[0]], wy = y[t[3]] - y[t[0]], wz = z[t[3]] - z[t[0]];
  return ((uy * vz - uz * vy) * wx + (uz * vx - ux * vz) * wy) + (ux * vy - uy * vx) * wz;
}

TetLattice::TetLattice(std::span<const geometry::Tet> tets, int node_count)
    : use_avx2_(cpu_has_avx2()) {
  // Without AVX2 the patterns would only be counted one by one as well: every tet is loose.
  std::map<std::array<int, 4>, std::vector<int>> slots_of_pattern;
  for (const auto& t : tets) {
    const int lowest = *std::min_element(t.begin(), t.end());
    slots_of_pattern[{t[0] - lowest, t[1] - lowest, t[2] - lowest, t[3] - lowest}].push_back(
        lowest);
  }
  for (const auto& [offsets, slots] : slots_of_pattern) {
    const int slot_count = node_count - *std::max_element(offsets.begin(), offsets.end());
    if (!use_avx2_ || slots.size() < kMinPatternFill * slot_count) {
      for (int m : slots)
        loose_.push_back({m + offsets[0], m + offsets[1], m + offsets[2], m + offsets[3]});
      continue;
    }
    Pattern p;
    p.offsets = offsets;
    p.slot_count = slot_count;
    p.occupied.assign(static_cast<std::size_t>(slot_count / 4 + 1), 0);
    for (int m : slots) p.occupied[m / 4] |= static_cast<std::uint8_t>(1 << (m % 4));
    for (int first = 0; first < slot_count; first += kSlotsPerChunk) {
      chunks_.push_back({static_cast<int>(patterns_.size()), first,
                         std::min(slot_count, first + kSlotsPerChunk)});
    }
    patterns_.push_back(std::move(p));
  }
  const int loose_count = static_cast<int>(loose_.size());
  for (int first = 0; first < loose_count; first += kLooseTetsPerChunk) {
    chunks_.push_back({-1, first, std::min(loose_count, first + kLooseTetsPerChunk)});
  }
}

int TetLattice::count(int chunk, const double* x, const double* y, const double* z) const {
  const Chunk& c = chunks_[chunk];
  if (c.pattern < 0) {
    int inverted = 0;
    for (int t = c.first; t < c.last; ++t) inverted += six_signed_volume(x, y, z, loose_[t]) <= 0.0;
    return inverted;
  }
#if defined(__x86_64__)
  const Pattern& p = patterns_[c.pattern];
  return count_inverted_avx2(p.offsets, p.occupied.data(), c.first, c.last, x, y, z);
#else
  return 0;  // no patterns without AVX2
#endif
}

}  // namespace ultrasim::sim::msds_detail
