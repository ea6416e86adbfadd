#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::geometry {

// One surface vertex tied to the tet mesh: the four nodes of its tet and its barycentric weights
// there (summing to 1). Node indices are stored directly, not the tet index, so the per-frame
// update reads one record per vertex and the nodes, nothing else.
struct EmbeddedVertex {
  std::array<std::int32_t, 4> nodes{};
  std::array<double, 4> weights{};
};

// Surface vertices embedded in a rest tet mesh by barycentric coordinates, so that they follow the
// mesh as it deforms (the published vessel surfaces, moved every frame from the deformed nodes).
//
// A vertex inside the rest mesh takes the tet TetLocator finds for it, and its weights are all in
// [0, 1]. A vertex outside the mesh (a surface closed half a voxel beyond the simulated region,
// say) takes the tet owning the boundary face nearest to it, with that tet's barycentric
// coordinates extended beyond it (some weights negative): it then moves by the tet's own affine
// motion, continuing the deformation outward rather than freezing. Either way an affine
// deformation of the mesh moves every vertex exactly by that affine map.
class SurfaceEmbedding {
 public:
  // Embeds rest_vertices_mm in `rest_mesh` at its rest positions. Allocates (a TetLocator, the
  // records); not for the frame loop. Throws std::invalid_argument for a mesh without tets.
  SurfaceEmbedding(const TetMesh& rest_mesh, std::span<const Eigen::Vector3d> rest_vertices_mm);

  int vertex_count() const { return static_cast<int>(vertices_.size()); }
  int node_count() const { return node_count_; }
  // How many vertices lay outside the rest mesh and were embedded by extrapolation.
  int outside_vertex_count() const { return outside_count_; }
  std::span<const EmbeddedVertex> vertices() const { return vertices_; }
  // The tet each vertex was embedded in (index into the rest mesh's tets).
  std::span<const std::int32_t> tets() const { return tets_; }

  // Moves every vertex from the deformed node positions (node_count() entries) into
  // vertices_out_mm (vertex_count() entries). Never allocates; any thread, as long as no other
  // thread writes the nodes or the same outputs meanwhile.
  void update(std::span<const Eigen::Vector3d> deformed_nodes_mm,
              std::span<Eigen::Vector3d> vertices_out_mm) const;

  // The same for vertices [begin, end) only, so a caller's threads can split the surface into
  // disjoint ranges and update them concurrently (the embedding itself is read-only). Writes only
  // vertices_out_mm[begin, end). Never allocates.
  void update_range(int begin, int end, std::span<const Eigen::Vector3d> deformed_nodes_mm,
                    std::span<Eigen::Vector3d> vertices_out_mm) const;

 private:
  std::vector<EmbeddedVertex> vertices_;
  std::vector<std::int32_t> tets_;
  int node_count_ = 0;
  int outside_count_ = 0;
};

}  // namespace ultrasim::geometry
