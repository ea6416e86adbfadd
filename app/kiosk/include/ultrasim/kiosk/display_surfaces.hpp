#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/surface_embedding.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/geometry/triangle_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/imaging/volume.hpp"
#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::kiosk {

// One structure's surface as the 3D view shows it: extracted from the label volume at display
// resolution, smoothed, and embedded in the rest tet mesh so it follows the tissue.
struct DisplaySurface {
  int label = 0;
  std::array<float, 4> rgba{};
  geometry::TriangleMesh rest;
  geometry::SurfaceEmbedding embedding;
  std::vector<std::uint32_t> triangle_indices;  // rest.triangles, flattened for the renderer
};

// The vein, artery, nerve and bone surfaces of a case (labels 4–7, each only if present), at
// about `voxel_mm` resolution: coarser than the case's voxels so the software renderer can afford
// them every frame. Allocates; at case load.
std::vector<DisplaySurface> build_display_surfaces(const imaging::Volume<std::uint8_t>& labels,
                                                   const geometry::TetMesh& rest_mesh,
                                                   double voxel_mm = 1.0);

// Per-frame deformed copies of a case's display surfaces, in the renderer's float layout.
class DeformedSurfaces {
 public:
  // Sizes every buffer once. `surfaces` must outlive this object.
  explicit DeformedSurfaces(std::span<const DisplaySurface> surfaces);

  // Moves every vertex with the deformed tet nodes and recomputes normals, spreading the work
  // over `jobs`. Does not allocate.
  void update(std::span<const Eigen::Vector3d> deformed_nodes_mm, hal::JobSystem& jobs);

  // Views for render::FrameInput::surfaces, valid until the next update().
  std::span<const render::SurfaceView> views() const { return views_; }

 private:
  struct Buffers {
    std::vector<Eigen::Vector3d> positions, normals;
    std::vector<float> positions_f, normals_f;
  };
  // A run of one surface's vertices or triangles, updated as one task.
  struct Chunk {
    int surface, begin, end;
  };
  static constexpr int kChunkVertices = 1024;
  static constexpr int kChunkTriangles = 2048;
  std::span<const DisplaySurface> surfaces_;
  std::vector<Buffers> buffers_;
  std::vector<geometry::SharedVertexNormals> normals_;  // a surface's
  std::vector<Chunk> vertex_chunks_, triangle_chunks_;
  std::vector<render::SurfaceView> views_;
};

}  // namespace ultrasim::kiosk
