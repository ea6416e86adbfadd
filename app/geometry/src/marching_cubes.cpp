#include "ultrasim/geometry/marching_cubes.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace ultrasim::geometry {

namespace {

// ---------------------------------------------------------------------------------------------
// The case table, derived from the cube's geometry and the face rule.
//
// Corner c of a cube sits at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1), as in tet_mesh.cpp.
// Edge 4·axis + n joins the n-th corner (in increasing order) whose `axis` bit is clear to the
// corner one step along `axis`. Face 2·axis + side holds the corners whose `axis` bit equals side.

constexpr int kCorners = 8;
constexpr int kEdges = 12;
constexpr int kFaces = 6;
constexpr int kCases = 256;

struct CubeEdge {
  int from = 0;  // corner with the axis bit clear
  int to = 0;    // corner with the axis bit set
  int axis = 0;
};

Eigen::Vector3d corner_offset(int c) {
  return {double(c & 1), double((c >> 1) & 1), double(c >> 2)};
}

std::array<CubeEdge, kEdges> make_cube_edges() {
  std::array<CubeEdge, kEdges> edges{};
  int e = 0;
  for (int axis = 0; axis < 3; ++axis) {
    for (int c = 0; c < kCorners; ++c) {
      if (((c >> axis) & 1) == 0) edges[e++] = {c, c | (1 << axis), axis};
    }
  }
  return edges;
}

struct CubeCase {
  std::uint16_t edge_mask = 0;                        // bit e: the surface crosses edge e
  std::vector<std::array<std::int8_t, 3>> triangles;  // cube edges, whose midpoints are vertices
};

using CaseTable = std::array<CubeCase, kCases>;

// Minimum-total-diagonal-length triangulation of a loop of edge midpoints, without any diagonal
// whose ends lie on a common cube face. A diagonal in a face could also be chosen by the cube on
// the other side of that face, giving an edge with four triangles; a diagonal between edges on no
// common face is interior to this cube, so no other cube can produce it. Returns false when every
// triangulation needs such a diagonal.
bool triangulate_loop(const std::vector<std::int8_t>& loop,
                      const std::array<Eigen::Vector3d, kEdges>& midpoint,
                      const std::array<std::array<bool, kEdges>, kEdges>& share_face,
                      std::vector<std::array<std::int8_t, 3>>& triangles) {
  const int n = static_cast<int>(loop.size());
  constexpr double kForbidden = std::numeric_limits<double>::infinity();
  const auto side_or_chord = [&](int i, int j) {
    if (j == i + 1 || (i == 0 && j == n - 1)) return 0.0;  // a loop side: a face segment
    if (share_face[loop[i]][loop[j]]) return kForbidden;
    return (midpoint[loop[i]] - midpoint[loop[j]]).norm();
  };
  // cost[i][j]: best triangulation of the sub-polygon loop[i..j] closed by the side/chord (i, j).
  std::vector<std::vector<double>> cost(n, std::vector<double>(n, 0.0));
  std::vector<std::vector<int>> split(n, std::vector<int>(n, -1));
  for (int length = 2; length < n; ++length) {
    for (int i = 0; i + length < n; ++i) {
      const int j = i + length;
      cost[i][j] = kForbidden;
      for (int k = i + 1; k < j; ++k) {
        const double c = cost[i][k] + cost[k][j] + side_or_chord(i, k) + side_or_chord(k, j);
        if (c < cost[i][j]) {
          cost[i][j] = c;
          split[i][j] = k;
        }
      }
    }
  }
  if (!(cost[0][n - 1] < kForbidden)) return false;
  std::vector<std::pair<int, int>> pending{{0, n - 1}};
  while (!pending.empty()) {
    const auto [i, j] = pending.back();
    pending.pop_back();
    if (j - i < 2) continue;
    const int k = split[i][j];
    // i < k < j keeps the loop's order, hence its orientation.
    triangles.push_back({loop[i], loop[k], loop[j]});
    pending.emplace_back(i, k);
    pending.emplace_back(k, j);
  }
  return true;
}

CaseTable build_case_table() {
  const std::array<CubeEdge, kEdges> edges = make_cube_edges();
  std::array<Eigen::Vector3d, kEdges> midpoint;
  for (int e = 0; e < kEdges; ++e) {
    midpoint[e] = (corner_offset(edges[e].from) + corner_offset(edges[e].to)) / 2.0;
  }
  const auto edge_between = [&](int a, int b) {
    for (int e = 0; e < kEdges; ++e) {
      if ((edges[e].from == a && edges[e].to == b) || (edges[e].from == b && edges[e].to == a)) {
        return e;
      }
    }
    throw std::logic_error("marching cubes: corners are not adjacent");
  };

  // Faces: corners in cyclic order, the edge from each corner to the next, the outward normal.
  std::array<std::array<int, 4>, kFaces> face_corners{};
  std::array<std::array<int, 4>, kFaces> face_edges{};
  std::array<Eigen::Vector3d, kFaces> face_normal;
  std::array<std::array<bool, kEdges>, kEdges> share_face{};
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      const int f = 2 * axis + side;
      const int base = side << axis;
      face_corners[f] = {base, base | (1 << u), base | (1 << u) | (1 << v), base | (1 << v)};
      for (int q = 0; q < 4; ++q) {
        face_edges[f][q] = edge_between(face_corners[f][q], face_corners[f][(q + 1) % 4]);
      }
      face_normal[f] = Eigen::Vector3d::Zero();
      face_normal[f][axis] = side ? 1.0 : -1.0;
      for (const int a : face_edges[f]) {
        for (const int b : face_edges[f]) share_face[a][b] = true;
      }
    }
  }

  CaseTable table;
  for (int config = 0; config < kCases; ++config) {
    const auto inside = [config](int corner) { return ((config >> corner) & 1) != 0; };
    CubeCase& cube = table[config];
    for (int e = 0; e < kEdges; ++e) {
      if (inside(edges[e].from) != inside(edges[e].to)) cube.edge_mask |= std::uint16_t(1u << e);
    }

    // Each face contributes directed segments between crossed edges. The direction puts the
    // inside corners on the right when the face is seen from outside the cube, which makes every
    // contour loop run counter-clockwise seen from outside the surface; the cube across the face
    // sees the opposite normal and so traverses the shared segment the opposite way.
    std::array<int, kEdges> next;
    next.fill(-1);
    const auto add_segment = [&](int f, int p, int q) {
      const int inside_corner = inside(edges[p].from) ? edges[p].from : edges[p].to;
      const Eigen::Vector3d along = midpoint[q] - midpoint[p];
      const Eigen::Vector3d to_inside = corner_offset(inside_corner) - midpoint[p];
      if (along.cross(to_inside).dot(face_normal[f]) > 0) std::swap(p, q);
      if (next[p] != -1) throw std::logic_error("marching cubes: vertex with two exits");
      next[p] = q;
    };
    for (int f = 0; f < kFaces; ++f) {
      std::array<int, 4> crossed{};
      int crossings = 0;
      for (int q = 0; q < 4; ++q) {
        if (inside(face_corners[f][q]) != inside(face_corners[f][(q + 1) % 4])) {
          crossed[crossings++] = face_edges[f][q];
        }
      }
      if (crossings == 2) {
        add_segment(f, crossed[0], crossed[1]);
      } else if (crossings == 4) {
        // The ambiguous face: cut each inside corner off on its own (the fixed rule).
        for (int q = 0; q < 4; ++q) {
          if (inside(face_corners[f][q])) {
            add_segment(f, face_edges[f][(q + 3) % 4], face_edges[f][q]);
          }
        }
      }
    }

    std::array<bool, kEdges> visited{};
    for (int start = 0; start < kEdges; ++start) {
      if (next[start] == -1 || visited[start]) continue;
      std::vector<std::int8_t> loop;
      for (int e = start; !visited[e]; e = next[e]) {
        if (next[e] == -1) throw std::logic_error("marching cubes: open contour");
        visited[e] = true;
        loop.push_back(static_cast<std::int8_t>(e));
      }
      if (loop.size() < 3) throw std::logic_error("marching cubes: degenerate contour");
      // With the separating face rule every loop of every case has such a triangulation (the
      // whole table is built here at first use, so a rule change that broke this fails at once).
      if (!triangulate_loop(loop, midpoint, share_face, cube.triangles)) {
        throw std::logic_error("marching cubes: contour loop without a safe triangulation");
      }
    }
  }
  return table;
}

const CaseTable& case_table() {
  static const CaseTable table = build_case_table();
  return table;
}

}  // namespace

TriangleMesh marching_cubes(const LabelGridView& grid, const LabelSet& inside,
                            MarchingCubesStats* stats) {
  if ((grid.size.array() < 0).any() ||
      grid.labels.size() != static_cast<std::size_t>(grid.size.cast<std::int64_t>().prod())) {
    throw std::invalid_argument("marching_cubes: labels.size() must equal size.x·size.y·size.z");
  }
  MarchingCubesStats local_stats;
  MarchingCubesStats& st = stats ? *stats : local_stats;
  st = {};
  TriangleMesh mesh;

  // Bounding box of the inside voxels: only cubes touching it can be cut, which for a vessel is a
  // small part of the volume.
  const Eigen::Vector3i n = grid.size;
  Eigen::Vector3i lo = n, hi = Eigen::Vector3i::Constant(-1);
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      const std::uint8_t* row = grid.labels.data() + static_cast<std::size_t>(n.x()) *
                                                         (j + static_cast<std::size_t>(n.y()) * k);
      int first = -1, last = -1;
      for (int i = 0; i < n.x(); ++i) {
        if (inside(row[i])) {
          if (first < 0) first = i;
          last = i;
        }
      }
      if (first < 0) continue;
      lo = lo.cwiseMin(Eigen::Vector3i(first, j, k));
      hi = hi.cwiseMax(Eigen::Vector3i(last, j, k));
    }
  }
  if ((hi.array() < 0).any()) return mesh;

  // Inside mask over the box grown by one voxel each way. The extra ring is outside (it is either
  // beyond the grid or, by the box's definition, not inside), which closes the surface.
  const Eigen::Vector3i mask_size = (hi - lo).array() + 3;
  const std::size_t mx = static_cast<std::size_t>(mask_size.x());
  const std::size_t mxy = mx * static_cast<std::size_t>(mask_size.y());
  std::vector<std::uint8_t> mask(mxy * static_cast<std::size_t>(mask_size.z()), 0);
  for (int k = lo.z(); k <= hi.z(); ++k) {
    for (int j = lo.y(); j <= hi.y(); ++j) {
      const std::uint8_t* row = grid.labels.data() + static_cast<std::size_t>(n.x()) *
                                                         (j + static_cast<std::size_t>(n.y()) * k);
      std::uint8_t* out = mask.data() + (k - lo.z() + 1) * mxy + (j - lo.y() + 1) * mx + 1;
      for (int i = lo.x(); i <= hi.x(); ++i) out[i - lo.x()] = inside(row[i]) ? 1 : 0;
    }
  }

  // Mask point (x, y, z) is grid index (lo - 1) + (x, y, z); world = origin + M · index.
  const Eigen::Matrix3d index_to_world = grid.direction * grid.spacing_mm.asDiagonal();
  const Eigen::Vector3d mask_origin_mm =
      grid.origin_mm + index_to_world * (lo.array() - 1).cast<double>().matrix();
  // A mirroring direction matrix turns outward-facing triangles inward: undo it.
  const bool mirrored = grid.direction.determinant() < 0;

  const CaseTable& table = case_table();
  const std::array<CubeEdge, kEdges> edges = make_cube_edges();
  std::array<std::size_t, kCorners> corner_step{};
  for (int c = 0; c < kCorners; ++c) {
    corner_step[c] = (c & 1) + ((c >> 1) & 1) * mx + (c >> 2) * mxy;
  }

  // Welding: a vertex per crossed grid edge, found again by the neighbouring cubes through these
  // caches. x- and y-edges live in the corner layer at z (bottom) or z + 1 (top) of the current
  // slab of cubes, z-edges in the slab itself; layers roll as the slab moves up.
  std::vector<std::int32_t> x_edges[2], y_edges[2], z_edges;
  for (int layer = 0; layer < 2; ++layer) {
    x_edges[layer].assign(mxy, -1);
    y_edges[layer].assign(mxy, -1);
  }
  z_edges.assign(mxy, -1);
  int bottom = 0;

  for (int z = 0; z + 1 < mask_size.z(); ++z) {
    const int top = 1 - bottom;
    std::fill(x_edges[top].begin(), x_edges[top].end(), -1);
    std::fill(y_edges[top].begin(), y_edges[top].end(), -1);
    std::fill(z_edges.begin(), z_edges.end(), -1);
    for (int y = 0; y + 1 < mask_size.y(); ++y) {
      for (int x = 0; x + 1 < mask_size.x(); ++x) {
        const std::size_t base = z * mxy + y * mx + x;
        int config = 0;
        for (int c = 0; c < kCorners; ++c) config |= mask[base + corner_step[c]] << c;
        ++st.cubes_visited;
        if (config == 0 || config == kCases - 1) continue;
        ++st.cubes_cut;
        const CubeCase& cube = table[config];

        std::array<std::int32_t, kEdges> vertex{};
        for (int e = 0; e < kEdges; ++e) {
          if (((cube.edge_mask >> e) & 1) == 0) continue;
          const CubeEdge& edge = edges[e];
          const int cx = edge.from & 1, cy = (edge.from >> 1) & 1, cz = edge.from >> 2;
          const std::size_t cell = (x + cx) + (y + cy) * mx;
          std::int32_t& slot = edge.axis == 0   ? x_edges[cz ? top : bottom][cell]
                               : edge.axis == 1 ? y_edges[cz ? top : bottom][cell]
                                                : z_edges[cell];
          if (slot < 0) {
            Eigen::Vector3d index(x + cx, y + cy, z + cz);
            index[edge.axis] += 0.5;
            slot = static_cast<std::int32_t>(mesh.vertices_mm.size());
            mesh.vertices_mm.push_back(mask_origin_mm + index_to_world * index);
          }
          vertex[e] = slot;
        }
        for (const auto& t : cube.triangles) {
          mesh.triangles.push_back(mirrored ? Triangle{vertex[t[0]], vertex[t[2]], vertex[t[1]]}
                                            : Triangle{vertex[t[0]], vertex[t[1]], vertex[t[2]]});
        }
      }
    }
    bottom = top;
  }
  return mesh;
}

}  // namespace ultrasim::geometry
