#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/triangle_mesh.hpp"

namespace ultrasim::geometry {

// Taubin's λ|μ filter ("Curve and surface smoothing without shrinkage", 1995): a shrinking
// Laplacian step with weight λ > 0 followed by an inflating one with μ < −λ. Frequencies below the
// pass-band k_PB = 1/λ + 1/μ (0.113 for the defaults) pass almost unchanged, so the surface keeps
// its volume while the marching-cubes staircase (the highest frequencies) is removed.
// "Almost": below k_PB each λ|μ pair amplifies by about 1 + (|μ| − λ)·k, and an object's overall
// size is such a low frequency with k ∝ 1/radius². Measured over 100 iterations of the defaults
// (tests/unit/geometry/smoothing_test.cpp): a sphere 20 voxels in radius gains 1 % of its volume,
// one of 6 voxels 10 %. For structures only a few voxels thick, take μ nearer −λ (−0.505: 1 %).
struct TaubinSettings {
  double lambda = 0.5;   // shrinking weight, in (0, 1]
  double mu = -0.53;     // inflating weight, < −lambda
  int iterations = 100;  // λ|μ pairs: each iteration is one λ step and one μ step
};

// Uniform-weight ("umbrella") Laplacian smoothing of a surface's vertices: each step moves every
// vertex by factor · (mean of its one-ring neighbours − itself), all vertices at once (Jacobi).
// Holds the one-ring adjacency (compressed rows) and one scratch buffer, so repeated steps
// allocate nothing. Uniform weights also even out triangle sizes, which suits marching-cubes
// output whose triangles come in a few fixed shapes.
class SurfaceSmoother {
 public:
  // Builds the adjacency of `triangles` over vertex_count vertices. Allocates. A vertex used by
  // no triangle keeps its position.
  SurfaceSmoother(int vertex_count, std::span<const Triangle> triangles);

  int vertex_count() const { return static_cast<int>(row_start_.size()) - 1; }

  // One step with the given factor (λ, or μ for Taubin's inflating step; any sign).
  // positions_mm.size() must equal vertex_count(). Never allocates; one thread at a time per
  // smoother.
  void step(std::span<Eigen::Vector3d> positions_mm, double factor);

  // The published "Gaussian" smoothing: `iterations` steps with weight lambda in (0, 1]. Shrinks
  // the surface a little every step. Throws std::invalid_argument on a bad lambda. Never
  // allocates.
  void laplacian(std::span<Eigen::Vector3d> positions_mm, double lambda, int iterations);

  // Taubin's λ|μ smoothing. Throws std::invalid_argument unless 0 < lambda <= 1 and
  // mu < −lambda. Never allocates.
  void taubin(std::span<Eigen::Vector3d> positions_mm, const TaubinSettings& settings);

 private:
  std::vector<std::int32_t> row_start_;   // vertex_count + 1 offsets into neighbours_
  std::vector<std::int32_t> neighbours_;  // one-ring vertices, each edge listed from both ends
  std::vector<Eigen::Vector3d> offset_;   // scratch: per vertex, mean of neighbours − itself
};

// Convenience: build a smoother for `mesh` and smooth its vertices in place. Allocates the
// smoother once, nothing per iteration. Any thread, one call per mesh at a time.
void laplacian_smooth(TriangleMesh& mesh, double lambda, int iterations);
void taubin_smooth(TriangleMesh& mesh, const TaubinSettings& settings = {});

}  // namespace ultrasim::geometry
