#pragma once

// sim::find_contacts written the obvious way: every free node asked for its closest point on the
// probe, no pre-reject. The reference the fast path is checked against
// (probe_collider_test.cpp) and timed against (tests/bench/contact_bench.cpp).

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/sim/contact.hpp"
#include "ultrasim/sim/probe_collider.hpp"

namespace ultrasim::testing {

inline void naive_find_contacts(const sim::ProbeCollider& probe,
                                std::span<const Eigen::Vector3d> positions_mm,
                                std::span<const std::uint8_t> fixed_nodes, double tolerance_mm,
                                std::vector<sim::NodeContact>& out) {
  out.clear();
  for (int node = 0; node < static_cast<int>(positions_mm.size()); ++node) {
    if (fixed_nodes[node]) continue;
    const Eigen::Vector3d& p = positions_mm[node];
    const sim::SurfacePoint s = probe.closest_surface_point(p);
    const double distance = (p - s.point_mm).dot(s.normal);
    if (!(distance < tolerance_mm)) continue;
    out.push_back({node, s.point_mm, s.normal, std::max(0.0, -distance)});
  }
}

}  // namespace ultrasim::testing
