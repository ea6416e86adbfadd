#include "ultrasim/geometry/surface_embedding.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>

#include "ultrasim/geometry/tet_locator.hpp"

namespace ultrasim::geometry {

namespace {

// A face of the rest mesh's boundary, with the tet it belongs to.
struct BoundaryFace {
  std::array<Eigen::Vector3d, 3> corner_mm;
  Eigen::Vector3d box_min_mm, box_max_mm;
  std::int32_t tet = -1;
};

// Faces used by exactly one tet, each with its owner. Tets too flat to invert are left out: their
// barycentric coordinates cannot be extended to outside points.
std::vector<BoundaryFace> boundary_faces_with_owner(const TetMesh& mesh) {
  struct Entry {
    std::array<std::int32_t, 3> sorted_nodes;
    std::int32_t tet;
  };
  std::vector<Entry> faces;
  faces.reserve(mesh.tets.size() * 4);
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      for (int c = 0, n = 0; c < 4; ++c) {
        if (c != skip) f[n++] = mesh.tets[t][c];
      }
      std::sort(f.begin(), f.end());
      faces.push_back({f, static_cast<std::int32_t>(t)});
    }
  }
  std::sort(faces.begin(), faces.end(),
            [](const Entry& a, const Entry& b) { return a.sorted_nodes < b.sorted_nodes; });
  std::vector<BoundaryFace> boundary;
  const auto& p = mesh.rest_positions_mm;
  for (std::size_t n = 0; n < faces.size();) {
    std::size_t end = n + 1;
    while (end < faces.size() && faces[end].sorted_nodes == faces[n].sorted_nodes) ++end;
    if (end - n == 1) {
      const Tet& tet = mesh.tets[faces[n].tet];
      const double volume = signed_tet_volume(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]);
      const double scale = (p[tet[1]] - p[tet[0]]).norm() * (p[tet[2]] - p[tet[0]]).norm() *
                           (p[tet[3]] - p[tet[0]]).norm();
      if (std::abs(volume) > 1e-12 * scale) {
        BoundaryFace face;
        for (int c = 0; c < 3; ++c) face.corner_mm[c] = p[faces[n].sorted_nodes[c]];
        face.box_min_mm = face.corner_mm[0].cwiseMin(face.corner_mm[1]).cwiseMin(face.corner_mm[2]);
        face.box_max_mm = face.corner_mm[0].cwiseMax(face.corner_mm[1]).cwiseMax(face.corner_mm[2]);
        face.tet = faces[n].tet;
        boundary.push_back(face);
      }
    }
    n = end;
  }
  return boundary;
}

// Squared distance from p to triangle (a, b, c): the closest point found by the Voronoi regions of
// the triangle's vertices, edges and interior, in barycentric terms.
double squared_distance_to_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();  // vertex a
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();  // vertex b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {  // edge ab
    return (p - (a + d1 / (d1 - d3) * ab)).squaredNorm();
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();  // vertex c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {  // edge ac
    return (p - (a + d2 / (d2 - d6) * ac)).squaredNorm();
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {  // edge bc
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return (p - (b + w * (c - b))).squaredNorm();
  }
  const double denominator = 1.0 / (va + vb + vc);  // interior
  return (p - (a + ab * (vb * denominator) + ac * (vc * denominator))).squaredNorm();
}

double squared_distance_to_box(const Eigen::Vector3d& p, const Eigen::Vector3d& lo,
                               const Eigen::Vector3d& hi) {
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm();
}

// Nearest boundary face queries through a uniform grid of cells over the faces' bounding boxes:
// a query visits shells of cells around the point's cell, nearest first, and stops once the next
// shell cannot hold anything closer than the best face so far. Cost per query is a few cells'
// faces, not the whole boundary (which grows with the mesh: stitched sub-volumes have many).
class BoundaryFaceGrid {
 public:
  explicit BoundaryFaceGrid(std::vector<BoundaryFace> faces) : faces_(std::move(faces)) {
    lo_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    hi_ = -lo_;
    double mean_extent = 0.0;
    for (const BoundaryFace& f : faces_) {
      lo_ = lo_.cwiseMin(f.box_min_mm);
      hi_ = hi_.cwiseMax(f.box_max_mm);
      mean_extent += (f.box_max_mm - f.box_min_mm).maxCoeff();
    }
    mean_extent = std::max(mean_extent / static_cast<double>(faces_.size()), 1e-9);
    const Eigen::Vector3d extent = (hi_ - lo_).cwiseMax(1e-9);
    for (int a = 0; a < 3; ++a) {
      cells_[a] = std::clamp(static_cast<int>(std::ceil(extent[a] / mean_extent)), 1, 128);
    }
    cell_mm_ = extent.cwiseQuotient(cells_.cast<double>());
    // Compressed rows: count the faces per cell, prefix-sum, fill.
    cell_start_.assign(static_cast<std::size_t>(cells_.prod()) + 1, 0);
    for_each_cell_of_faces([&](std::size_t cell, std::int32_t) { ++cell_start_[cell + 1]; });
    for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
    cell_faces_.resize(static_cast<std::size_t>(cell_start_.back()));
    std::vector<std::int32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for_each_cell_of_faces(
        [&](std::size_t cell, std::int32_t f) { cell_faces_[fill[cell]++] = f; });
  }

  std::int32_t nearest_tet(const Eigen::Vector3d& p) const {
    // Distances from p to anything in the grid's box are at least those from p's projection onto
    // the box (the box is convex), so the shell bound below holds for points outside it too.
    const Eigen::Vector3d inside = p.cwiseMax(lo_).cwiseMin(hi_);
    const Eigen::Vector3i centre = cell_of(inside);
    const double min_cell = cell_mm_.minCoeff();
    double best_d2 = std::numeric_limits<double>::infinity();
    std::int32_t best = -1;
    const int max_shell = cells_.maxCoeff();
    for (int r = 0; r <= max_shell; ++r) {
      // A cell r shells away lies at least (r - 1) whole cells from any point of the centre cell.
      const double bound = std::max(0, r - 1) * min_cell;
      if (bound * bound >= best_d2) break;
      const Eigen::Vector3i from = (centre.array() - r).max(0);
      const Eigen::Vector3i to = (centre.array() + r).min(cells_.array() - 1);
      for (int k = from.z(); k <= to.z(); ++k) {
        for (int j = from.y(); j <= to.y(); ++j) {
          for (int i = from.x(); i <= to.x(); ++i) {
            const int shell = std::max(
                {std::abs(i - centre.x()), std::abs(j - centre.y()), std::abs(k - centre.z())});
            if (shell != r) continue;
            const std::size_t cell =
                i + cells_.x() * (j + static_cast<std::size_t>(cells_.y()) * k);
            for (std::int32_t n = cell_start_[cell]; n < cell_start_[cell + 1]; ++n) {
              const BoundaryFace& face = faces_[cell_faces_[n]];
              if (squared_distance_to_box(p, face.box_min_mm, face.box_max_mm) >= best_d2) continue;
              const double d2 = squared_distance_to_triangle(p, face.corner_mm[0],
                                                             face.corner_mm[1], face.corner_mm[2]);
              if (d2 < best_d2) {
                best_d2 = d2;
                best = cell_faces_[n];
              }
            }
          }
        }
      }
    }
    return faces_[best].tet;
  }

 private:
  Eigen::Vector3i cell_of(const Eigen::Vector3d& p) const {
    Eigen::Vector3i c;
    for (int a = 0; a < 3; ++a) {
      c[a] = std::clamp(static_cast<int>((p[a] - lo_[a]) / cell_mm_[a]), 0, cells_[a] - 1);
    }
    return c;
  }

  template <typename Visit>
  void for_each_cell_of_faces(Visit visit) const {
    for (std::size_t f = 0; f < faces_.size(); ++f) {
      const Eigen::Vector3i a = cell_of(faces_[f].box_min_mm), b = cell_of(faces_[f].box_max_mm);
      for (int k = a.z(); k <= b.z(); ++k)
        for (int j = a.y(); j <= b.y(); ++j)
          for (int i = a.x(); i <= b.x(); ++i)
            visit(i + cells_.x() * (j + static_cast<std::size_t>(cells_.y()) * k),
                  static_cast<std::int32_t>(f));
    }
  }

  std::vector<BoundaryFace> faces_;
  Eigen::Vector3d lo_, hi_, cell_mm_;
  Eigen::Vector3i cells_;
  std::vector<std::int32_t> cell_start_;  // per cell: offset into cell_faces_, cell count + 1
  std::vector<std::int32_t> cell_faces_;
};

// Barycentric coordinates of p in tet t at rest, valid (extended affinely) outside the tet too.
std::array<double, 4> barycentric_in(const TetMesh& mesh, std::int32_t t,
                                     const Eigen::Vector3d& p) {
  const Tet& tet = mesh.tets[t];
  const auto& x = mesh.rest_positions_mm;
  Eigen::Matrix3d edges;
  edges << x[tet[1]] - x[tet[0]], x[tet[2]] - x[tet[0]], x[tet[3]] - x[tet[0]];
  const Eigen::Vector3d l = edges.partialPivLu().solve(p - x[tet[0]]);
  return {1.0 - l.sum(), l.x(), l.y(), l.z()};
}

}  // namespace

SurfaceEmbedding::SurfaceEmbedding(const TetMesh& rest_mesh,
                                   std::span<const Eigen::Vector3d> rest_vertices_mm)
    : vertices_(rest_vertices_mm.size()),
      tets_(rest_vertices_mm.size(), -1),
      node_count_(rest_mesh.node_count()) {
  if (rest_mesh.tets.empty()) throw std::invalid_argument("SurfaceEmbedding: mesh has no tets");
  const TetLocator locator(rest_mesh);
  std::optional<BoundaryFaceGrid> boundary;  // built on the first vertex outside the mesh
  for (std::size_t v = 0; v < rest_vertices_mm.size(); ++v) {
    const Eigen::Vector3d& p = rest_vertices_mm[v];
    std::int32_t tet = -1;
    std::array<double, 4> weights{};
    if (const auto found = locator.locate(p)) {
      tet = found->tet;
      for (int c = 0; c < 4; ++c) weights[c] = found->barycentric[c];
    } else {
      if (!p.allFinite()) throw std::invalid_argument("SurfaceEmbedding: non-finite vertex");
      if (!boundary) {
        std::vector<BoundaryFace> faces = boundary_faces_with_owner(rest_mesh);
        if (faces.empty()) throw std::invalid_argument("SurfaceEmbedding: all tets are flat");
        boundary.emplace(std::move(faces));
      }
      tet = boundary->nearest_tet(p);
      weights = barycentric_in(rest_mesh, tet, p);
      ++outside_count_;
    }
    tets_[v] = tet;
    vertices_[v].nodes = rest_mesh.tets[tet];
    vertices_[v].weights = weights;
  }
}

void SurfaceEmbedding::update(std::span<const Eigen::Vector3d> deformed_nodes_mm,
                              std::span<Eigen::Vector3d> vertices_out_mm) const {
  update_range(0, vertex_count(), deformed_nodes_mm, vertices_out_mm);
}

void SurfaceEmbedding::update_range(int begin, int end,
                                    std::span<const Eigen::Vector3d> deformed_nodes_mm,
                                    std::span<Eigen::Vector3d> vertices_out_mm) const {
  if (begin < 0 || end < begin || end > vertex_count() ||
      vertices_out_mm.size() != vertices_.size() ||
      deformed_nodes_mm.size() != static_cast<std::size_t>(node_count_)) {
    throw std::invalid_argument("SurfaceEmbedding::update_range: sizes do not match the embedding");
  }
  const Eigen::Vector3d* nodes = deformed_nodes_mm.data();
  for (int v = begin; v < end; ++v) {
    const EmbeddedVertex& e = vertices_[v];
    vertices_out_mm[v] = e.weights[0] * nodes[e.nodes[0]] + e.weights[1] * nodes[e.nodes[1]] +
                         e.weights[2] * nodes[e.nodes[2]] + e.weights[3] * nodes[e.nodes[3]];
  }
}

}  // namespace ultrasim::geometry
