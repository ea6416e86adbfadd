#include "ultrasim/geometry/triangle_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace ultrasim::geometry {

void compute_vertex_normals(std::span<const Eigen::Vector3d> positions_mm,
                            std::span<const Triangle> triangles,
                            std::span<Eigen::Vector3d> normals_out) {
  std::fill(normals_out.begin(), normals_out.end(), Eigen::Vector3d::Zero());
  for (const Triangle& t : triangles) {
    const Eigen::Vector3d& a = positions_mm[t[0]];
    // The unnormalised cross product is twice the triangle's area along its normal, so summing it
    // weights each triangle by its area: large, well-shaped triangles dominate slivers.
    const Eigen::Vector3d n = (positions_mm[t[1]] - a).cross(positions_mm[t[2]] - a);
    for (int c = 0; c < 3; ++c) normals_out[t[c]] += n;
  }
  for (Eigen::Vector3d& n : normals_out) {
    const double length = n.norm();
    n = length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
  }
}

SharedVertexNormals::SharedVertexNormals(int vertex_count, std::span<const Triangle> triangles)
    : triangles_(triangles.begin(), triangles.end()),
      first_incident_(static_cast<std::size_t>(std::max(vertex_count, 0)) + 1, 0),
      incident_(3 * triangles.size()),
      triangle_normals_(triangles.size()) {
  for (const Triangle& t : triangles_) {
    for (const std::int32_t v : t) {
      if (v < 0 || v >= vertex_count) {
        throw std::invalid_argument("SharedVertexNormals: a triangle's vertex index " +
                                    std::to_string(v) + " is outside the " +
                                    std::to_string(vertex_count) + " vertices");
      }
      ++first_incident_[static_cast<std::size_t>(v) + 1];
    }
  }
  for (std::size_t v = 1; v < first_incident_.size(); ++v) {
    first_incident_[v] += first_incident_[v - 1];
  }
  std::vector<int> next(first_incident_.begin(), first_incident_.end() - 1);
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    for (const std::int32_t v : triangles_[t]) incident_[next[v]++] = static_cast<int>(t);
  }
}

void SharedVertexNormals::triangle_normals(std::span<const Eigen::Vector3d> positions_mm, int begin,
                                           int end) {
  for (int t = begin; t < end; ++t) {
    const Triangle& tri = triangles_[t];
    const Eigen::Vector3d& a = positions_mm[tri[0]];
    // As compute_vertex_normals: twice the area along the normal, so large triangles weigh more.
    triangle_normals_[t] = (positions_mm[tri[1]] - a).cross(positions_mm[tri[2]] - a);
  }
}

void SharedVertexNormals::vertex_normals(int begin, int end,
                                         std::span<Eigen::Vector3d> normals_out) const {
  for (int v = begin; v < end; ++v) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (int i = first_incident_[v]; i < first_incident_[v + 1]; ++i) {
      n += triangle_normals_[incident_[i]];
    }
    const double length = n.norm();
    normals_out[v] = length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
  }
}

std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh) {
  std::vector<Eigen::Vector3d> normals(mesh.vertices_mm.size());
  compute_vertex_normals(mesh.vertices_mm, mesh.triangles, normals);
  return normals;
}

double enclosed_volume_mm3(std::span<const Eigen::Vector3d> positions_mm,
                           std::span<const Triangle> triangles) {
  // Signed tets against a point near the surface rather than the world origin: the sum is the same
  // for a closed surface, but the terms are small, so far-from-origin meshes lose no precision.
  if (triangles.empty()) return 0.0;
  const Eigen::Vector3d reference = positions_mm[triangles.front()[0]];
  double six_volume = 0.0;
  for (const Triangle& t : triangles) {
    const Eigen::Vector3d a = positions_mm[t[0]] - reference;
    const Eigen::Vector3d b = positions_mm[t[1]] - reference;
    const Eigen::Vector3d c = positions_mm[t[2]] - reference;
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

double enclosed_volume_mm3(const TriangleMesh& mesh) {
  return enclosed_volume_mm3(mesh.vertices_mm, mesh.triangles);
}

double surface_area_mm2(std::span<const Eigen::Vector3d> positions_mm,
                        std::span<const Triangle> triangles) {
  double twice_area = 0.0;
  for (const Triangle& t : triangles) {
    const Eigen::Vector3d& a = positions_mm[t[0]];
    twice_area += (positions_mm[t[1]] - a).cross(positions_mm[t[2]] - a).norm();
  }
  return twice_area / 2.0;
}

double surface_area_mm2(const TriangleMesh& mesh) {
  return surface_area_mm2(mesh.vertices_mm, mesh.triangles);
}

MeshTopologyReport check_closed_oriented(const TriangleMesh& mesh) {
  MeshTopologyReport report;
  const auto vertex_count = static_cast<std::uint64_t>(mesh.vertices_mm.size());
  // Each directed edge a → b as one 64-bit key; after sorting, the copies of an undirected edge
  // {a, b} are found by looking up both directions.
  std::vector<std::uint64_t> directed;
  directed.reserve(mesh.triangles.size() * 3);
  const auto key = [](std::uint64_t from, std::uint64_t to) { return (from << 32) | to; };
  for (const Triangle& t : mesh.triangles) {
    bool valid = true;
    for (int c = 0; c < 3; ++c) {
      valid = valid && t[c] >= 0 && static_cast<std::uint64_t>(t[c]) < vertex_count;
    }
    if (!valid || t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
      ++report.degenerate_triangles;
      continue;
    }
    for (int c = 0; c < 3; ++c) {
      directed.push_back(
          key(static_cast<std::uint64_t>(t[c]), static_cast<std::uint64_t>(t[(c + 1) % 3])));
    }
  }
  std::sort(directed.begin(), directed.end());
  const auto count_of = [&](std::uint64_t k) {
    const auto range = std::equal_range(directed.begin(), directed.end(), k);
    return static_cast<int>(range.second - range.first);
  };
  for (std::size_t n = 0; n < directed.size();) {
    std::size_t end = n;
    while (end < directed.size() && directed[end] == directed[n]) ++end;
    const int forward = static_cast<int>(end - n);
    const std::uint64_t from = directed[n] >> 32, to = directed[n] & 0xffffffffu;
    const int backward = count_of(key(to, from));
    // Visit each undirected edge once: from its lower-keyed direction, or from the only direction
    // present.
    if (backward == 0 || key(from, to) < key(to, from)) {
      const int uses = forward + backward;
      if (uses == 1) {
        ++report.boundary_edges;
      } else if (uses > 2) {
        ++report.non_manifold_edges;
      } else if (forward != 1) {  // uses == 2, both the same direction
        ++report.misoriented_edges;
      }
    }
    n = end;
  }
  return report;
}

}  // namespace ultrasim::geometry
