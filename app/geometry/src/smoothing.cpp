#include "ultrasim/geometry/smoothing.hpp"

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <utility>

namespace ultrasim::geometry {

SurfaceSmoother::SurfaceSmoother(int vertex_count, std::span<const Triangle> triangles) {
  if (vertex_count < 0) throw std::invalid_argument("SurfaceSmoother: negative vertex count");
  // Every triangle side from both ends, sorted and deduplicated: each vertex's one-ring once.
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
  pairs.reserve(triangles.size() * 6);
  for (const Triangle& t : triangles) {
    for (int c = 0; c < 3; ++c) {
      const std::int32_t a = t[c], b = t[(c + 1) % 3];
      if (a < 0 || b < 0 || a >= vertex_count || b >= vertex_count) {
        throw std::invalid_argument("SurfaceSmoother: triangle index out of range");
      }
      if (a == b) continue;
      pairs.emplace_back(a, b);
      pairs.emplace_back(b, a);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  row_start_.assign(static_cast<std::size_t>(vertex_count) + 1, 0);
  for (const auto& p : pairs) ++row_start_[static_cast<std::size_t>(p.first) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(vertex_count); ++v) {
    row_start_[v + 1] += row_start_[v];
  }
  neighbours_.resize(pairs.size());
  for (std::size_t n = 0; n < pairs.size(); ++n) neighbours_[n] = pairs[n].second;
  offset_.resize(static_cast<std::size_t>(vertex_count));
}

void SurfaceSmoother::step(std::span<Eigen::Vector3d> positions_mm, double factor) {
  if (positions_mm.size() != offset_.size()) {
    throw std::invalid_argument("SurfaceSmoother: positions do not match the mesh");
  }
  const std::size_t count = offset_.size();
  // Two passes so every vertex sees its neighbours' old positions (a simultaneous update, as
  // Taubin's analysis assumes; updating in place would make the result depend on vertex order).
  for (std::size_t v = 0; v < count; ++v) {
    const std::int32_t begin = row_start_[v], end = row_start_[v + 1];
    if (begin == end) {
      offset_[v].setZero();
      continue;
    }
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::int32_t n = begin; n < end; ++n) sum += positions_mm[neighbours_[n]];
    offset_[v] = sum / static_cast<double>(end - begin) - positions_mm[v];
  }
  for (std::size_t v = 0; v < count; ++v) positions_mm[v] += factor * offset_[v];
}

void SurfaceSmoother::laplacian(std::span<Eigen::Vector3d> positions_mm, double lambda,
                                int iterations) {
  if (!(lambda > 0.0 && lambda <= 1.0)) {
    throw std::invalid_argument("laplacian smoothing: lambda must be in (0, 1]");
  }
  for (int i = 0; i < iterations; ++i) step(positions_mm, lambda);
}

void SurfaceSmoother::taubin(std::span<Eigen::Vector3d> positions_mm,
                             const TaubinSettings& settings) {
  if (!(settings.lambda > 0.0 && settings.lambda <= 1.0)) {
    throw std::invalid_argument("taubin smoothing: lambda must be in (0, 1]");
  }
  if (!(settings.mu < -settings.lambda)) {
    throw std::invalid_argument("taubin smoothing: mu must be < -lambda");
  }
  for (int i = 0; i < settings.iterations; ++i) {
    step(positions_mm, settings.lambda);
    step(positions_mm, settings.mu);
  }
}

void laplacian_smooth(TriangleMesh& mesh, double lambda, int iterations) {
  SurfaceSmoother smoother(mesh.vertex_count(), mesh.triangles);
  smoother.laplacian(mesh.vertices_mm, lambda, iterations);
}

void taubin_smooth(TriangleMesh& mesh, const TaubinSettings& settings) {
  SurfaceSmoother smoother(mesh.vertex_count(), mesh.triangles);
  smoother.taubin(mesh.vertices_mm, settings);
}

}  // namespace ultrasim::geometry
