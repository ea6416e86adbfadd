#include "ultrasim/kiosk/display_surfaces.hpp"

#include <algorithm>
#include <cmath>

#include "ultrasim/geometry/marching_cubes.hpp"
#include "ultrasim/geometry/smoothing.hpp"

namespace ultrasim::kiosk {

namespace {

struct StructureStyle {
  int label;
  std::array<float, 4> rgba;
};
// Colours trainees know from anatomy atlases: veins blue, arteries red, nerves yellow.
constexpr std::array<StructureStyle, 4> kStructures = {{
    {4, {0.25f, 0.45f, 0.95f, 1.0f}},  // vein
    {5, {0.90f, 0.20f, 0.20f, 1.0f}},  // artery
    {6, {0.95f, 0.85f, 0.30f, 1.0f}},  // nerve
    {7, {0.92f, 0.90f, 0.80f, 1.0f}},  // bone
}};

// Every stride-th voxel (nearest, labels must not blend).
imaging::Volume<std::uint8_t> subsample(const imaging::Volume<std::uint8_t>& labels, int stride) {
  const Eigen::Vector3i size = (labels.size().array() - 1) / stride + 1;
  imaging::Volume<std::uint8_t> out(size, labels.spacing_mm() * stride, labels.origin_mm(),
                                    labels.direction());
  for (int k = 0; k < size.z(); ++k)
    for (int j = 0; j < size.y(); ++j)
      for (int i = 0; i < size.x(); ++i)
        out.at(i, j, k) = labels.at(i * stride, j * stride, k * stride);
  return out;
}

}  // namespace

std::vector<DisplaySurface> build_display_surfaces(const imaging::Volume<std::uint8_t>& labels,
                                                   const geometry::TetMesh& rest_mesh,
                                                   double voxel_mm) {
  const int stride =
      std::max(1, static_cast<int>(std::lround(voxel_mm / labels.spacing_mm().minCoeff())));
  const imaging::Volume<std::uint8_t> coarse = subsample(labels, stride);
  std::array<bool, 256> present{};
  for (auto v : coarse.voxels()) present[v] = true;

  const geometry::LabelGridView grid{coarse.size(), coarse.spacing_mm(), coarse.origin_mm(),
                                     coarse.direction(), coarse.voxels()};
  std::vector<DisplaySurface> surfaces;
  for (const auto& style : kStructures) {
    if (!present[style.label]) continue;
    geometry::TriangleMesh mesh =
        geometry::marching_cubes(grid, geometry::LabelSet{static_cast<std::uint8_t>(style.label)});
    if (mesh.triangles.empty()) continue;
    geometry::taubin_smooth(mesh, geometry::TaubinSettings{0.5, -0.53, 30});
    geometry::SurfaceEmbedding embedding(rest_mesh, mesh.vertices_mm);
    std::vector<std::uint32_t> indices;
    indices.reserve(mesh.triangles.size() * 3);
    for (const auto& t : mesh.triangles)
      for (auto v : t) indices.push_back(static_cast<std::uint32_t>(v));
    surfaces.push_back(DisplaySurface{style.label, style.rgba, std::move(mesh),
                                      std::move(embedding), std::move(indices)});
  }
  return surfaces;
}

DeformedSurfaces::DeformedSurfaces(std::span<const DisplaySurface> surfaces)
    : surfaces_(surfaces), buffers_(surfaces.size()), views_(surfaces.size()) {
  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    const std::size_t n = surfaces[s].rest.vertices_mm.size();
    buffers_[s].positions.assign(n, Eigen::Vector3d::Zero());
    buffers_[s].normals.assign(n, Eigen::Vector3d::Zero());
    buffers_[s].positions_f.assign(3 * n, 0.0f);
    buffers_[s].normals_f.assign(3 * n, 0.0f);
    views_[s].positions_mm = buffers_[s].positions_f;
    views_[s].normals = buffers_[s].normals_f;
    views_[s].triangles = surfaces[s].triangle_indices;
    views_[s].rgba = surfaces[s].rgba;
    normals_.emplace_back(static_cast<int>(n), surfaces[s].rest.triangles);
    const auto add_chunks = [s](std::vector<Chunk>& chunks, int count, int size) {
      for (int begin = 0; begin < count; begin += size) {
        chunks.push_back({static_cast<int>(s), begin, std::min(count, begin + size)});
      }
    };
    add_chunks(vertex_chunks_, static_cast<int>(n), kChunkVertices);
    add_chunks(triangle_chunks_, surfaces[s].rest.triangle_count(), kChunkTriangles);
  }
}

void DeformedSurfaces::update(std::span<const Eigen::Vector3d> deformed_nodes_mm,
                              hal::JobSystem& jobs) {
  // Each pass in chunks over every surface: the large case's bone has as many vertices as its
  // three vessels together, and one task per surface left a thread idle through its normals
  // (0.23 of the view's 0.65 ms a frame).
  hal::parallel_for(jobs, static_cast<int>(vertex_chunks_.size()), [&](int c) {
    const Chunk& chunk = vertex_chunks_[c];
    Buffers& b = buffers_[chunk.surface];
    surfaces_[chunk.surface].embedding.update_range(chunk.begin, chunk.end, deformed_nodes_mm,
                                                    b.positions);
    for (int v = chunk.begin; v < chunk.end; ++v) {
      for (int a = 0; a < 3; ++a) b.positions_f[3 * v + a] = static_cast<float>(b.positions[v][a]);
    }
  });
  hal::parallel_for(jobs, static_cast<int>(triangle_chunks_.size()), [&](int c) {
    const Chunk& chunk = triangle_chunks_[c];
    normals_[chunk.surface].triangle_normals(buffers_[chunk.surface].positions, chunk.begin,
                                             chunk.end);
  });
  hal::parallel_for(jobs, static_cast<int>(vertex_chunks_.size()), [&](int c) {
    const Chunk& chunk = vertex_chunks_[c];
    Buffers& b = buffers_[chunk.surface];
    normals_[chunk.surface].vertex_normals(chunk.begin, chunk.end, b.normals);
    for (int v = chunk.begin; v < chunk.end; ++v) {
      for (int a = 0; a < 3; ++a) b.normals_f[3 * v + a] = static_cast<float>(b.normals[v][a]);
    }
  });
}

}  // namespace ultrasim::kiosk
