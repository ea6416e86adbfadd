// The portable span kernels (trilinear_span.hpp): one pixel at a time.

#include "trilinear_span.hpp"

#include <algorithm>

namespace ultrasim::imaging::slicer_detail {

namespace {

// Everything it reads is copied into locals first, because its byte stores could alias any
// memory the compiler would otherwise have to reload.
template <bool kClamp>
void sample_span(const VoxelGrid& g, const double* index_at_col0, const double* step, int first,
                 int last, std::uint8_t* out) {
  const std::uint8_t* const voxels = g.voxels;
  const int stride_y = static_cast<int>(g.stride_y), stride_z = static_cast<int>(g.stride_z);
  const std::ptrdiff_t step_x = g.step_x, step_y = g.step_y, step_z = g.step_z;
  const int max_i = g.max_i, max_j = g.max_j, max_k = g.max_k;
  const double x0 = index_at_col0[0], y0 = index_at_col0[1], z0 = index_at_col0[2];
  const double dx = step[0], dy = step[1], dz = step[2];
  for (int col = first; col <= last; ++col) {
    const double c = col;
    const double xi = x0 + c * dx, yi = y0 + c * dy, zi = z0 + c * dz;
    // Indices are >= -1e-9, so truncation is floor (or 0 for the hair below it).
    int i = static_cast<int>(xi), j = static_cast<int>(yi), k = static_cast<int>(zi);
    if constexpr (kClamp) {
      i = std::min(i, max_i);
      j = std::min(j, max_j);
      k = std::min(k, max_k);
    }
    const double fx = xi - i, fy = yi - j, fz = zi - k;
    const std::uint8_t* p = voxels + (i + j * stride_y + k * stride_z);
    const std::uint8_t* q = p + step_z;
    const double c00 = p[0] + (p[step_x] - p[0]) * fx;
    const double c10 = p[step_y] + (p[step_y + step_x] - p[step_y]) * fx;
    const double c01 = q[0] + (q[step_x] - q[0]) * fx;
    const double c11 = q[step_y] + (q[step_y + step_x] - q[step_y]) * fx;
    const double c0 = c00 + (c10 - c00) * fy;
    const double c1 = c01 + (c11 - c01) * fy;
    // Rounded to the nearest grey level and clamped, as echo_to_grey does.
    const double grey = std::min(std::max(c0 + (c1 - c0) * fz + 0.5, 0.0), 255.0);
    out[col] = static_cast<std::uint8_t>(grey);
  }
}

}  // namespace

VoxelGrid voxel_grid_of(const Volume<std::uint8_t>& volume) {
  const Eigen::Vector3i n = volume.size();
  VoxelGrid g;
  g.voxels = volume.voxels().data();
  g.stride_y = n.x();
  g.stride_z = static_cast<std::ptrdiff_t>(n.x()) * n.y();
  g.step_x = n.x() > 1 ? 1 : 0;
  g.step_y = n.y() > 1 ? g.stride_y : 0;
  g.step_z = n.z() > 1 ? g.stride_z : 0;
  g.max_i = std::max(n.x() - 2, 0);
  g.max_j = std::max(n.y() - 2, 0);
  g.max_k = std::max(n.z() - 2, 0);
  return g;
}

void portable_inside_span(const VoxelGrid& grid, const double* index_at_col0, const double* step,
                          int first, int last, std::uint8_t* out) {
  sample_span<false>(grid, index_at_col0, step, first, last, out);
}

void portable_clamped_span(const VoxelGrid& grid, const double* index_at_col0, const double* step,
                           int first, int last, std::uint8_t* out) {
  sample_span<true>(grid, index_at_col0, step, first, last, out);
}

}  // namespace ultrasim::imaging::slicer_detail
