#include "ultrasim/sim/contact.hpp"

#include <algorithm>

namespace ultrasim::sim {

void find_contacts(const ProbeCollider& probe, std::span<const Eigen::Vector3d> positions_mm,
                   std::span<const std::uint8_t> fixed_nodes, double tolerance_mm,
                   std::vector<NodeContact>& out) {
  out.clear();
  // A node outside the probe's box grown by the tolerance is farther than that from the probe,
  // whatever its shape (a stitched sub-volume's nodes mostly are: the closest-point query, a
  // change of frame and a clamp, was most of the corotational FEM's constraints, 0.07 ms of a 15³
  // sub-volume's step).
  // The box is grown by a hair more, so that rounding in its corners cannot leave out a node the
  // query would take.
  Eigen::AlignedBox3d reach = probe.bounds_mm();
  const double grow = tolerance_mm + 1e-9 * (1.0 + reach.diagonal().norm());
  reach.min().array() -= grow;
  reach.max().array() += grow;
  for (int node = 0; node < static_cast<int>(positions_mm.size()); ++node) {
    if (fixed_nodes[node]) continue;
    const Eigen::Vector3d& p = positions_mm[node];
    if (!reach.contains(p)) continue;
    const SurfacePoint s = probe.closest_surface_point(p);
    const double distance = (p - s.point_mm).dot(s.normal);
    if (!(distance < tolerance_mm)) continue;
    out.push_back({node, s.point_mm, s.normal, std::max(0.0, -distance)});
  }
}

SurfacePoint slide_held_node(const ProbeCollider& probe, const SurfacePoint& held,
                             const Eigen::Vector3d& tissue_force_mn,
                             const Eigen::Matrix3d& stiffness, double friction_coefficient) {
  const double push_mn = -tissue_force_mn.dot(held.normal);
  if (!(push_mn > 0.0)) return held;  // pulled off the probe (or NaN): not ours to move
  const Eigen::Vector3d along_mn = tissue_force_mn + push_mn * held.normal;
  const double pull_mn = along_mn.norm();
  const double excess_mn = pull_mn - friction_coefficient * push_mn;
  if (!(excess_mn > 0.0)) return held;
  const Eigen::Vector3d direction = along_mn / pull_mn;
  const double stiffness_along = direction.dot(stiffness * direction);
  if (!(stiffness_along > 0.0)) return held;
  const double slide_mm = std::min(excess_mn / stiffness_along, kMaxSlidePerStepMm);
  return probe.closest_surface_point(held.point_mm + slide_mm * direction);
}

HeldNodeLaw coulomb_hold(const Eigen::Vector3d& normal, const Eigen::Vector3d& tissue_force_mn,
                         double friction_coefficient) {
  if (!tissue_force_mn.allFinite()) return {};
  // Pulled off the probe (the caller lets go of it next): no friction holds it along the surface.
  const double push_mn = std::max(0.0, -tissue_force_mn.dot(normal));
  const Eigen::Vector3d along_mn = tissue_force_mn - tissue_force_mn.dot(normal) * normal;
  const double pull_mn = along_mn.norm();
  const double bound_mn = friction_coefficient * push_mn;
  if (bound_mn > 0.0 && pull_mn <= bound_mn) return {};
  HeldNodeLaw law;
  law.slides = true;
  if (pull_mn > 0.0) law.friction_mn = -(bound_mn / pull_mn) * along_mn;
  return law;
}

}  // namespace ultrasim::sim
