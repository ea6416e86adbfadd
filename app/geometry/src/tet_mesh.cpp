#include "ultrasim/geometry/tet_mesh.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>
#include <utility>

namespace ultrasim::geometry {

namespace {

// Cell corner c in [0, 8) sits at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1). The corners with
// odd coordinate sum (1, 2, 4, 7) form the central tet of an "even" cell; each even corner
// (0, 3, 5, 6) with its three edge neighbours forms a corner tet. "Odd" cells swap the roles.
constexpr std::array<std::array<int, 4>, 5> kEvenCellTets = {{
    {1, 2, 4, 7},  // central
    {0, 1, 2, 4},
    {3, 1, 2, 7},
    {5, 1, 4, 7},
    {6, 2, 4, 7},
}};
constexpr std::array<std::array<int, 4>, 5> kOddCellTets = {{
    {0, 3, 5, 6},  // central
    {1, 0, 3, 5},
    {2, 0, 3, 6},
    {4, 0, 5, 6},
    {7, 3, 5, 6},
}};

}  // namespace

GridSpec GridSpec::spanning(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm,
                            const Eigen::Vector3i& nodes) {
  if ((nodes.array() < 2).any()) throw std::invalid_argument("grid needs >= 2 nodes per axis");
  if (!((max_mm - min_mm).array() > 0).all()) {
    throw std::invalid_argument("grid region must have min < max on every axis");
  }
  GridSpec grid;
  grid.nodes = nodes;
  grid.origin_mm = min_mm;
  grid.spacing_mm = (max_mm - min_mm).cwiseQuotient((nodes.array() - 1).cast<double>().matrix());
  return grid;
}

double signed_tet_volume(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a) / 6.0;
}

int count_inverted_tets(std::span<const std::array<std::int32_t, 4>> tets,
                        std::span<const Eigen::Vector3d> positions_mm) {
  int inverted = 0;
  for (const auto& t : tets) {
    const auto& p = positions_mm;
    inverted += signed_tet_volume(p[t[0]], p[t[1]], p[t[2]], p[t[3]]) <= 0.0;
  }
  return inverted;
}

TetMesh make_grid_tet_mesh(const GridSpec& grid) {
  if ((grid.nodes.array() < 2).any()) throw std::invalid_argument("grid needs >= 2 nodes per axis");
  if (!(grid.spacing_mm.array() > 0).all()) throw std::invalid_argument("grid spacing must be > 0");

  TetMesh mesh;
  mesh.rest_positions_mm.reserve(static_cast<std::size_t>(grid.node_count()));
  for (int k = 0; k < grid.nodes.z(); ++k) {
    for (int j = 0; j < grid.nodes.y(); ++j) {
      for (int i = 0; i < grid.nodes.x(); ++i) {
        mesh.rest_positions_mm.push_back(grid.node_position_mm(i, j, k));
      }
    }
  }

  const Eigen::Vector3i cells = grid.nodes.array() - 1;
  mesh.tets.reserve(static_cast<std::size_t>(cells.prod()) * 5);
  for (int k = 0; k < cells.z(); ++k) {
    for (int j = 0; j < cells.y(); ++j) {
      for (int i = 0; i < cells.x(); ++i) {
        std::array<std::int32_t, 8> corner{};
        for (int c = 0; c < 8; ++c) {
          corner[c] = grid.node_index(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        }
        const auto& pattern = ((i + j + k) % 2 == 0) ? kEvenCellTets : kOddCellTets;
        for (const auto& local : pattern) {
          Tet tet{corner[local[0]], corner[local[1]], corner[local[2]], corner[local[3]]};
          const auto& p = mesh.rest_positions_mm;
          if (signed_tet_volume(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) < 0) {
            std::swap(tet[2], tet[3]);
          }
          mesh.tets.push_back(tet);
        }
      }
    }
  }
  return mesh;
}

std::vector<std::array<std::int32_t, 3>> boundary_faces(const TetMesh& mesh) {
  // Faces of a positively oriented tet (a, b, c, d), each wound to face outwards.
  constexpr std::array<std::array<int, 3>, 4> kFaces = {
      {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};
  // Every tet's faces keyed by their sorted nodes, sorted by key: a key met once is a boundary
  // face, kept as its tet wound it (in key order).
  using Face = std::array<std::int32_t, 3>;
  std::vector<std::pair<Face, Face>> faces;  // (key, wound)
  faces.reserve(4 * mesh.tets.size());
  for (const Tet& tet : mesh.tets) {
    for (const auto& f : kFaces) {
      const Face wound{tet[f[0]], tet[f[1]], tet[f[2]]};
      Face key = wound;
      std::sort(key.begin(), key.end());
      faces.emplace_back(key, wound);
    }
  }
  std::sort(faces.begin(), faces.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Face> result;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].first == faces[i].first) ++j;
    if (j - i == 1) result.push_back(faces[i].second);
    i = j;
  }
  return result;
}

std::vector<std::uint8_t> boundary_node_flags(const TetMesh& mesh) {
  std::vector<std::uint8_t> on_boundary(mesh.rest_positions_mm.size(), 0);
  for (const auto& face : boundary_faces(mesh)) {
    for (std::int32_t node : face) on_boundary[node] = 1;
  }
  return on_boundary;
}

std::vector<std::array<std::int32_t, 2>> unique_edges(
    const std::vector<std::array<std::int32_t, 3>>& triangles) {
  std::vector<std::array<std::int32_t, 2>> edges;
  edges.reserve(triangles.size() * 3);
  for (const auto& t : triangles) {
    for (int e = 0; e < 3; ++e) {
      const std::int32_t a = t[e], b = t[(e + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

std::vector<std::array<std::int32_t, 2>> grid_surface_lines(const GridSpec& grid, int stride) {
  stride = std::max(stride, 1);
  const Eigen::Vector3i n = grid.nodes;
  const auto on_level = [stride](int v, int count) { return v % stride == 0 || v == count - 1; };
  const auto on_face = [](int v, int count) { return v == 0 || v == count - 1; };
  std::vector<std::array<std::int32_t, 2>> lines;
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        const int here = grid.node_index(i, j, k);
        // A segment along one axis lies on a face when one of the other two coordinates is on
        // the box's boundary, and on a drawn grid line when the remaining one is on the level.
        if (i + 1 < n.x() && ((on_face(j, n.y()) && on_level(k, n.z())) ||
                              (on_face(k, n.z()) && on_level(j, n.y())))) {
          lines.push_back({here, grid.node_index(i + 1, j, k)});
        }
        if (j + 1 < n.y() && ((on_face(i, n.x()) && on_level(k, n.z())) ||
                              (on_face(k, n.z()) && on_level(i, n.x())))) {
          lines.push_back({here, grid.node_index(i, j + 1, k)});
        }
        if (k + 1 < n.z() && ((on_face(i, n.x()) && on_level(j, n.y())) ||
                              (on_face(j, n.y()) && on_level(i, n.x())))) {
          lines.push_back({here, grid.node_index(i, j, k + 1)});
        }
      }
    }
  }
  return lines;
}

}  // namespace ultrasim::geometry
