#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::geometry {

// Where a point lies in a tet mesh: the tet and the point's barycentric coordinates in it
// (weights of the tet's four nodes, summing to 1).
struct TetLocation {
  std::int32_t tet = -1;
  Eigen::Vector4d barycentric = Eigen::Vector4d::Zero();
};

// Point location in a (deformed) tet mesh through a uniform grid of bins over the tets' bounding
// boxes. Rebuild it whenever node positions change; queries are then read-only and may run from
// many threads at once.
class TetLocator {
 public:
  // Binds the locator to a mesh's connectivity (copied) and sizes its buffers. Allocates.
  explicit TetLocator(const TetMesh& mesh);

  // Re-bins the tets at the given node positions (node_count entries). Allocates only when the
  // bin count grows past what earlier calls needed. Tets whose volume is not positive (inverted
  // or flat) cannot hold a point and are left out.
  void rebuild(std::span<const Eigen::Vector3d> positions_mm);

  // The tet containing p (barycentric coordinates all >= -1e-9), or nothing when p is outside
  // the mesh. Where p lies on a shared face, any of the tets sharing it may be returned.
  std::optional<TetLocation> locate(const Eigen::Vector3d& p_mm) const;

  int degenerate_tet_count() const { return degenerate_tets_; }

 private:
  bool bin_of(const Eigen::Vector3d& p, Eigen::Vector3i& bin) const;

  std::vector<Tet> tets_;
  std::vector<Eigen::Vector3d> origin_;   // per tet: node 0 position
  std::vector<Eigen::Matrix3d> inverse_;  // per tet: inverse of [p1-p0, p2-p0, p3-p0]
  std::vector<std::uint8_t> usable_;      // per tet: positive volume
  Eigen::Vector3d bins_min_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d bin_size_ = Eigen::Vector3d::Ones();
  Eigen::Vector3i bins_ = Eigen::Vector3i::Ones();
  std::vector<std::int32_t> bin_start_;  // CSR offsets, bin count + 1
  std::vector<std::int32_t> bin_tets_;   // tet indices, grouped by bin
  std::vector<std::array<int, 6>> tet_bin_range_;
  std::vector<std::int32_t> scratch_fill_;
  int degenerate_tets_ = 0;
};

}  // namespace ultrasim::geometry
