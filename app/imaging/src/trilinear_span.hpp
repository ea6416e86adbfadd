#pragma once

// The fast slicer's hot loop (internal to FastSlicer): trilinear samples of the volume along one
// row span of a cut tet, as grey levels. Two implementations of the same arithmetic: a portable
// one (the build's baseline ISA, one pixel at a time) and an AVX2 one (four pixels at a time,
// picked at run time where the CPU has AVX2). Both do the same IEEE operations in the same order
// (no FMA contraction), so they write bitwise the same bytes (slicer_agreement_test.cpp).

#include <cstddef>
#include <cstdint>

#include "ultrasim/imaging/fast_slicer.hpp"
#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging::slicer_detail {

// What the span kernels read of the volume, gathered once per slice_rows() call.
struct VoxelGrid {
  const std::uint8_t* voxels = nullptr;
  std::ptrdiff_t stride_y = 0, stride_z = 0;  // voxels per index step in j and k
  std::ptrdiff_t step_x = 0, step_y = 0,
                 step_z = 0;            // neighbour offsets (0 along a one-voxel axis)
  int max_i = 0, max_j = 0, max_k = 0;  // largest lower corner of a trilinear cell
};

VoxelGrid voxel_grid_of(const Volume<std::uint8_t>& volume);

// A SpanKernel (fast_slicer.hpp) samples at voxel indices index_at_col0 + col · step (three
// doubles each) for col in [first, last], written to out[col]. The index of each pixel is computed
// from its column, not stepped from its neighbour's, so that any number of lanes gives the same
// roundings. A `clamped` kernel lets indices reach the last voxel plane (and 1e-9 beyond either
// end); an `inside` one needs every pixel's cell whole inside the volume (x in [0, size.x - 1),
// ...), as for tets whose rest position stays clear of the volume's edge. Both read only the
// voxels of each pixel's cell.
struct SpanKernels {
  SpanKernel inside = nullptr;
  SpanKernel clamped = nullptr;
};

// One pixel at a time: the reference, and what every CPU runs (the AVX2 kernels too, on a
// volume one voxel thick along x).
void portable_inside_span(const VoxelGrid& grid, const double* index_at_col0, const double* step,
                          int first, int last, std::uint8_t* out);
void portable_clamped_span(const VoxelGrid& grid, const double* index_at_col0, const double* step,
                           int first, int last, std::uint8_t* out);
inline SpanKernels portable_span_kernels() {
  return {&portable_inside_span, &portable_clamped_span};
}
// AVX2 where the CPU has it (x86-64), otherwise the portable kernels.
SpanKernels fastest_span_kernels();

}  // namespace ultrasim::imaging::slicer_detail
