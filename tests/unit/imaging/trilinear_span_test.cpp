// The fast slicer's span kernels (internal: app/imaging/src/trilinear_span.hpp): the AVX2 kernels
// write bitwise what the portable ones write, on spans of every length from one pixel, inside the
// volume and clamped at its edges (its very last voxel included), on volumes one voxel thick
// along each axis, and touch no byte outside the span (none at all for an empty one).

#include "../../../app/imaging/src/trilinear_span.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <vector>

namespace ultrasim::imaging::slicer_detail {
namespace {

constexpr std::uint8_t kUntouched = 7;
constexpr int kImageWidth = 160;

// Hashed voxels over the whole grey range, 0 and 255 included.
Volume<std::uint8_t> hashed_volume(const Eigen::Vector3i& size) {
  Volume<std::uint8_t> v(size, {0.5, 0.5, 0.5}, {0, 0, 0});
  auto voxels = v.voxels();
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    voxels[i] = static_cast<std::uint8_t>((i * 2654435761u) >> 13);
  }
  return v;
}

struct Span {
  std::array<double, 3> at_col0, step;
  int first, last;
};

// A span of `pixels` from voxel index a to b (each inside [lo, hi] per axis), starting at a
// random column of the image row.
Span span_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b, int pixels,
                  std::mt19937& rng) {
  std::uniform_int_distribution<int> start(0, kImageWidth - pixels);
  Span s;
  s.first = start(rng);
  s.last = s.first + pixels - 1;
  for (int axis = 0; axis < 3; ++axis) {
    s.step[axis] = pixels > 1 ? (b[axis] - a[axis]) / (pixels - 1) : 0.0;
    s.at_col0[axis] = a[axis] - s.first * s.step[axis];
  }
  return s;
}

// Both kernels of one kind over the span; the rows they write must be the same bytes.
void expect_same_row(const VoxelGrid& grid, SpanKernel fastest, SpanKernel portable, const Span& s,
                     const char* what) {
  std::vector<std::uint8_t> a(kImageWidth, kUntouched), b(kImageWidth, kUntouched);
  fastest(grid, s.at_col0.data(), s.step.data(), s.first, s.last, a.data());
  portable(grid, s.at_col0.data(), s.step.data(), s.first, s.last, b.data());
  ASSERT_EQ(a, b) << what << ": span of " << s.last - s.first + 1 << " pixels from column "
                  << s.first;
  for (int col = 0; col < kImageWidth; ++col) {
    if (col < s.first || col > s.last) {
      ASSERT_EQ(a[col], kUntouched) << what << " column " << col;
    }
  }
}

bool fastest_is_portable() {
  return fastest_span_kernels().inside == portable_span_kernels().inside;
}

TEST(TrilinearSpan, FastestKernelsWriteThePortableKernelsBytes) {
  if (fastest_is_portable()) GTEST_SKIP() << "this CPU has no AVX2: one kernel, nothing to compare";
  const SpanKernels fastest = fastest_span_kernels(), portable = portable_span_kernels();
  std::mt19937 rng(1907);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> length(1, 60);
  int inside_spans = 0;
  for (const Eigen::Vector3i& size :
       {Eigen::Vector3i(37, 23, 19), Eigen::Vector3i(1, 23, 19), Eigen::Vector3i(37, 1, 19),
        Eigen::Vector3i(37, 23, 1), Eigen::Vector3i(2, 2, 2)}) {
    const Volume<std::uint8_t> volume = hashed_volume(size);
    const VoxelGrid grid = voxel_grid_of(volume);
    const Eigen::Vector3d top = size.cast<double>().array() - 1.0;
    for (int trial = 0; trial < 3000; ++trial) {
      // Clamped: anywhere from 1e-9 below the first voxel plane to 1e-9 past the last; every
      // tenth span ends on the volume's far corner, the last voxel it holds.
      const auto clamped_point = [&] {
        Eigen::Vector3d p;
        for (int axis = 0; axis < 3; ++axis) p[axis] = -1e-9 + (top[axis] + 2e-9) * unit(rng);
        return p;
      };
      const Eigen::Vector3d a = clamped_point();
      const Eigen::Vector3d b =
          trial % 10 == 0 ? Eigen::Vector3d(top.array() + 1e-9) : clamped_point();
      expect_same_row(grid, fastest.clamped, portable.clamped, span_between(a, b, length(rng), rng),
                      "clamped");
      // Inside: each pixel's cell whole in the volume (the kernels' contract).
      const Eigen::Vector3d hi = top.array() - 1e-6;
      if ((hi.array() < 0.0).any()) continue;  // one voxel thick: no whole cell
      const auto inside_point = [&] {
        Eigen::Vector3d p;
        for (int axis = 0; axis < 3; ++axis) p[axis] = hi[axis] * unit(rng);
        return p;
      };
      const Span inside = span_between(inside_point(), inside_point(), length(rng), rng);
      ++inside_spans;
      expect_same_row(grid, fastest.inside, portable.inside, inside, "inside");
    }
  }
  EXPECT_GT(inside_spans, 5000);  // the thin volumes have no whole cell
}

TEST(TrilinearSpan, AnEmptySpanWritesNothing) {
  // The slicer's rows can clip a span to nothing (last < first); no kernel may write then.
  const Volume<std::uint8_t> volume = hashed_volume({9, 8, 7});
  const VoxelGrid grid = voxel_grid_of(volume);
  const std::array<double, 3> at_col0 = {1.0, 1.0, 1.0}, step = {0.1, 0.0, 0.0};
  for (const SpanKernels& kernels : {fastest_span_kernels(), portable_span_kernels()}) {
    for (const SpanKernel kernel : {kernels.inside, kernels.clamped}) {
      std::vector<std::uint8_t> row(kImageWidth, kUntouched);
      kernel(grid, at_col0.data(), step.data(), 10, 9, row.data());
      kernel(grid, at_col0.data(), step.data(), 10, 6, row.data());
      EXPECT_EQ(row, std::vector<std::uint8_t>(kImageWidth, kUntouched));
    }
  }
}

}  // namespace
}  // namespace ultrasim::imaging::slicer_detail
