#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace ultrasim::geometry {

// A regular node grid: nodes.x × nodes.y × nodes.z nodes, node (i, j, k) at
// origin_mm + (i, j, k) ⊙ spacing_mm.
struct GridSpec {
  Eigen::Vector3i nodes = Eigen::Vector3i::Constant(2);
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();

  int node_count() const { return nodes.prod(); }
  int node_index(int i, int j, int k) const { return i + nodes.x() * (j + nodes.y() * k); }
  Eigen::Vector3d node_position_mm(int i, int j, int k) const {
    return origin_mm + Eigen::Vector3d(i, j, k).cwiseProduct(spacing_mm);
  }
  // Grid covering [min_mm, max_mm] with the given node counts (each >= 2).
  static GridSpec spanning(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm,
                           const Eigen::Vector3i& nodes);
};

using Tet = std::array<std::int32_t, 4>;  // node indices, positively oriented

// A conforming tetrahedral mesh. Rest positions are the undeformed configuration in which the
// case volume is embedded; deformed positions live with the simulation.
struct TetMesh {
  std::vector<Eigen::Vector3d> rest_positions_mm;
  std::vector<Tet> tets;

  int node_count() const { return static_cast<int>(rest_positions_mm.size()); }
  int tet_count() const { return static_cast<int>(tets.size()); }
};

// The published regular-grid mesher: every grid cell split into 5 tetrahedra (one central tet and
// four corner tets), with the split mirrored in alternate cells so that neighbouring cells cut
// their shared face along the same diagonal and the mesh conforms. Allocates.
TetMesh make_grid_tet_mesh(const GridSpec& grid);

// Signed volume of tet (a, b, c, d): positive when (b-a, c-a, d-a) is right-handed.
double signed_tet_volume(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c, const Eigen::Vector3d& d);

// Tets whose volume at `positions_mm` (one per node) is not positive: turned inside out.
int count_inverted_tets(std::span<const std::array<std::int32_t, 4>> tets,
                        std::span<const Eigen::Vector3d> positions_mm);

// Triangles on the mesh boundary (faces used by exactly one tet), outward-facing. Allocates.
std::vector<std::array<std::int32_t, 3>> boundary_faces(const TetMesh& mesh);

// One flag per node: 1 for a node of a boundary face (the mesh's surface), 0 inside. Allocates.
std::vector<std::uint8_t> boundary_node_flags(const TetMesh& mesh);

// Unique undirected edges of the given triangles, as index pairs (lower index first). Allocates.
std::vector<std::array<std::int32_t, 2>> unique_edges(
    const std::vector<std::array<std::int32_t, 3>>& triangles);

// The grid's box drawn as a wireframe at a level of detail: on its six faces, the grid lines
// through every `stride`-th node (and the last), segment by segment between neighbouring nodes so
// the lines follow the deformed nodes. Index pairs, lower index first. stride 1 is every grid
// line (without the tets' face diagonals). Allocates.
std::vector<std::array<std::int32_t, 2>> grid_surface_lines(const GridSpec& grid, int stride);

}  // namespace ultrasim::geometry
