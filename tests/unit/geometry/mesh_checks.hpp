#pragma once

// Topology checks shared by the surface tests: beyond check_closed_oriented (edges), that every
// vertex is a single fan (no pinched vertices), and the Euler characteristic.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ultrasim/geometry/triangle_mesh.hpp"

namespace ultrasim::geometry {

// Every vertex's triangles form one fan (its link is a single cycle): no pinched vertices. Together
// with check_closed_oriented this makes the surface a closed 2-manifold.
inline bool every_vertex_is_a_single_fan(const TriangleMesh& mesh) {
  std::vector<std::map<std::int32_t, std::int32_t>> link(mesh.vertices_mm.size());
  for (const Triangle& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) {
      if (!link[t[c]].emplace(t[(c + 1) % 3], t[(c + 2) % 3]).second) return false;
    }
  }
  for (const auto& ring : link) {
    if (ring.empty()) return false;  // an unused vertex
    std::int32_t at = ring.begin()->first;
    std::size_t steps = 0;
    do {
      const auto next = ring.find(at);
      if (next == ring.end()) return false;
      at = next->second;
      ++steps;
    } while (at != ring.begin()->first && steps <= ring.size());
    if (steps != ring.size()) return false;
  }
  return true;
}

inline int euler_characteristic(const TriangleMesh& mesh) {
  std::set<std::pair<std::int32_t, std::int32_t>> edges;
  for (const Triangle& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) {
      edges.emplace(std::min(t[c], t[(c + 1) % 3]), std::max(t[c], t[(c + 1) % 3]));
    }
  }
  return mesh.vertex_count() - static_cast<int>(edges.size()) + mesh.triangle_count();
}

inline void expect_closed_manifold(const TriangleMesh& mesh, const std::string& what) {
  const MeshTopologyReport report = check_closed_oriented(mesh);
  EXPECT_TRUE(report.closed_and_oriented())
      << what << ": boundary " << report.boundary_edges << ", non-manifold "
      << report.non_manifold_edges << ", misoriented " << report.misoriented_edges
      << ", degenerate " << report.degenerate_triangles;
  EXPECT_TRUE(every_vertex_is_a_single_fan(mesh)) << what;
}

}  // namespace ultrasim::geometry
