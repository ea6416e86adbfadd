#include <cmath>
#include <stdexcept>
#include <string>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {

namespace {

// Builds the message only when there is one to give: the check runs every stitched frame.
[[noreturn]] void reject(std::size_t index, const AnchorSpring& anchor, const std::string& why) {
  throw std::invalid_argument("anchor spring " + std::to_string(index) + " (node " +
                              std::to_string(anchor.node) + "): " + why);
}

}  // namespace

void check_anchor_springs(std::span<const AnchorSpring> anchors, int node_count) {
  int previous = -1;
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    const AnchorSpring& a = anchors[i];
    if (a.node < 0 || a.node >= node_count) {
      reject(i, a, "node outside the mesh of " + std::to_string(node_count) + " nodes");
    }
    if (a.node <= previous) reject(i, a, "nodes must be strictly increasing");
    if (!a.target_mm.allFinite()) reject(i, a, "target is not finite");
    if (!(std::isfinite(a.stiffness_mn_per_mm) && a.stiffness_mn_per_mm >= 0.0)) {
      reject(i, a, "stiffness must be finite and >= 0");
    }
    previous = a.node;
  }
}

}  // namespace ultrasim::sim
