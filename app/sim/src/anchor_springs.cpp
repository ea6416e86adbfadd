#include <cmath>
#include <stdexcept>
#include <string>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {

void check_anchor_springs(std::span<const AnchorSpring> anchors, int node_count) {
  int previous = -1;
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    const AnchorSpring& a = anchors[i];
    const std::string where =
        "anchor spring " + std::to_string(i) + " (node " + std::to_string(a.node) + "): ";
    if (a.node < 0 || a.node >= node_count) {
      throw std::invalid_argument(where + "node outside the mesh of " + std::to_string(node_count) +
                                  " nodes");
    }
    if (a.node <= previous) {
      throw std::invalid_argument(where + "nodes must be strictly increasing");
    }
    if (!a.target_mm.allFinite()) throw std::invalid_argument(where + "target is not finite");
    if (!(std::isfinite(a.stiffness_mn_per_mm) && a.stiffness_mn_per_mm >= 0.0)) {
      throw std::invalid_argument(where + "stiffness must be finite and >= 0");
    }
    previous = a.node;
  }
}

}  // namespace ultrasim::sim
