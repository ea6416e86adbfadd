#include "ultrasim/sim/contact.hpp"

#include <algorithm>

namespace ultrasim::sim {

void find_contacts(const ProbeCollider& probe, std::span<const Eigen::Vector3d> positions_mm,
                   std::span<const std::uint8_t> fixed_nodes, double tolerance_mm,
                   std::vector<NodeContact>& out) {
  out.clear();
  const SphereCollider bound = probe.bounding_sphere();
  const bool sphere = probe.shape() == ProbeCollider::Shape::kSphere;
  for (int node = 0; node < static_cast<int>(positions_mm.size()); ++node) {
    if (fixed_nodes[node]) continue;
    const Eigen::Vector3d& p = positions_mm[node];
    if (sphere && (p - bound.center_mm).squaredNorm() >=
                      (bound.radius_mm + tolerance_mm) * (bound.radius_mm + tolerance_mm)) {
      continue;  // cheap rejection for the common case: most nodes are far from the probe
    }
    const SurfacePoint s = probe.closest_surface_point(p);
    const double distance = (p - s.point_mm).dot(s.normal);
    if (!(distance < tolerance_mm)) continue;
    out.push_back({node, s.point_mm, s.normal, std::max(0.0, -distance)});
  }
}

}  // namespace ultrasim::sim
