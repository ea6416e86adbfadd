#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <initializer_list>
#include <span>

#include "ultrasim/geometry/triangle_mesh.hpp"

namespace ultrasim::geometry {

// A read-only view of a label volume, laid out as ITK/MetaImage (and imaging::Volume) lay it out:
// voxel (i, j, k) is labels[i + size.x · (j + size.y · k)] and sits at world position
// origin_mm + direction · diag(spacing_mm) · (i, j, k). Geometry defines its own view so that it
// does not depend on imaging; a caller fills it from a Volume's accessors. Owns nothing.
struct LabelGridView {
  Eigen::Vector3i size = Eigen::Vector3i::Zero();
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  std::span<const std::uint8_t> labels;
};

// Which labels count as inside the surface (e.g. {4} for the vein, {7} for bone).
struct LabelSet {
  std::array<bool, 256> contains{};

  LabelSet() = default;
  LabelSet(std::initializer_list<std::uint8_t> labels) {
    for (const std::uint8_t label : labels) contains[label] = true;
  }
  bool operator()(std::uint8_t label) const { return contains[label]; }
};

// What marching_cubes did, for tests and benchmarks.
struct MarchingCubesStats {
  std::int64_t cubes_visited = 0;  // cubes inside the inside set's bounding box (+1 voxel)
  std::int64_t cubes_cut = 0;      // cubes the surface passes through
};

// The boundary of the voxels whose label is in `inside`, as a closed, outward-facing, watertight
// triangle mesh with welded vertices (an edge is shared by exactly two triangles, in opposite
// directions). Voxels outside the grid count as outside, so surfaces touching the volume's border
// are closed by a cap half a voxel beyond it.
//
// Method: marching cubes on the dual grid of voxel centres, with vertices at the midpoints of cube
// edges whose ends differ (binary data carries no sub-voxel position; smoothing supplies it).
// Ambiguous faces (two inside corners on a diagonal) are always resolved by separating the inside
// corners. Because the rule depends only on a face's four corners, the two cubes sharing a face cut
// it the same way and the surface has no holes; it also makes the surface follow 6-connectivity of
// the inside voxels, as the voxels' own faces do. The cube's contour loops follow from its six
// faces; each loop is triangulated (shortest diagonals) with no diagonal lying in a cube face: such
// a diagonal could be chosen by the neighbouring cube too, giving an edge with four triangles,
// while one through the cube's interior belongs to this cube alone. Under the separating rule
// every loop of all 256 cases has such a triangulation. The per-case table is derived from these
// rules at first use, not copied from a published table.
//
// Throws std::invalid_argument when labels.size() != size.prod(). Allocates; any thread (the table
// is built once, thread-safely). Not for the frame loop: about 10 ms per structure of the
// 241×161×181 default case on one core, most of it spent only inside the structure's bounding box.
TriangleMesh marching_cubes(const LabelGridView& grid, const LabelSet& inside,
                            MarchingCubesStats* stats = nullptr);

}  // namespace ultrasim::geometry
