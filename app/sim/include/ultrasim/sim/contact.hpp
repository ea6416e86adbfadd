#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/sim/probe_collider.hpp"

namespace ultrasim::sim {

// A tissue node the probe touches this frame: where the collider puts it (the closest point of
// the probe's surface) and the probe's outward normal there.
struct NodeContact {
  int node = 0;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double depth_mm = 0.0;  // how far inside the probe the node was (≥ 0)
};

// The published collision test: every free node whose current position lies inside the probe
// (signed distance below `tolerance_mm`, so a node left exactly on the surface last frame stays
// in contact) is a contact, to be pushed out to the surface. `out` is cleared first; it keeps its
// capacity, so a step does not allocate once it has seen its largest contact set.
void find_contacts(const ProbeCollider& probe, std::span<const Eigen::Vector3d> positions_mm,
                   std::span<const std::uint8_t> fixed_nodes, double tolerance_mm,
                   std::vector<NodeContact>& out);

}  // namespace ultrasim::sim
