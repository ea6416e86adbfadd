#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {

// The nodes a filtered CG lets slide this frame (the PCG and corotational FEM's Coulomb slip, the
// fine correction's grid nodes): each held along one normal only, free in the plane across it,
// against a friction load. Sized once; nothing allocates after construction.
class SlidingNodes {
 public:
  explicit SlidingNodes(int node_count) : slides_(node_count, 0), hold_(node_count) {
    nodes_.reserve(node_count);
  }

  // No node slides.
  void clear() {
    for (int node : nodes_) slides_[node] = 0;
    nodes_.clear();
  }
  // `node` (not already sliding) slides along the plane across `normal` against `friction_mn`.
  void add(int node, const Eigen::Vector3d& normal, const Eigen::Vector3d& friction_mn) {
    slides_[node] = 1;
    hold_[node] = {normal, friction_mn};
    nodes_.push_back(node);
  }

  bool slides(int node) const { return slides_[node] != 0; }
  const DeformationEngine::SlidingHold* hold(int node) const {
    return slides_[node] ? &hold_[node] : nullptr;
  }
  std::span<const int> nodes() const { return nodes_; }

  // v minus its part along the sliding node's normal.
  void project(int node, Eigen::Ref<Eigen::Vector3d> v) const {
    const Eigen::Vector3d& n = hold_[node].normal;
    v -= v.dot(n) * n;
  }
  // The same at every sliding node of a node-major vector.
  void project_all(Eigen::VectorXd& v) const {
    for (int node : nodes_) project(node, v.segment<3>(3 * node));
  }
  // forces_mn += every sliding node's friction.
  void add_friction(Eigen::VectorXd& forces_mn) const {
    for (int node : nodes_) forces_mn.segment<3>(3 * node) += hold_[node].friction_mn;
  }
  // The force the probe exerts on a sliding node that `held_force_mn` (K u) holds: its push
  // along the normal and the friction. What K u has besides is a CG's unfinished imbalance, not
  // a force a probe exerts (the same at convergence).
  Eigen::Vector3d probe_force_mn(int node, const Eigen::Vector3d& held_force_mn) const {
    const DeformationEngine::SlidingHold& h = hold_[node];
    return held_force_mn.dot(h.normal) * h.normal + h.friction_mn;
  }

 private:
  std::vector<std::uint8_t> slides_;
  std::vector<DeformationEngine::SlidingHold> hold_;  // valid where slides_ is set
  std::vector<int> nodes_;
};

// A correction's move of a FEM whose CG slides nodes (DeformationEngine::displace_free_nodes_mm,
// the PCG and corotational FEMs): u_mm += du_mm at every node `engine` does not hold, and at each
// sliding node not prescribed since the step (it stays where it was put) du_mm's part in its
// tangent plane.
inline void displace_free_and_sliding_nodes(const DeformationEngine& engine,
                                            const SlidingNodes& sliding,
                                            std::span<const std::uint8_t> prescribed,
                                            const Eigen::VectorXd& du_mm, Eigen::VectorXd& u_mm) {
  const auto nodes = static_cast<int>(prescribed.size());
  for (int node = 0; node < nodes; ++node) {
    if (!engine.holds_node(node)) u_mm.segment<3>(3 * node) += du_mm.segment<3>(3 * node);
  }
  for (int node : sliding.nodes()) {
    if (prescribed[node]) continue;
    Eigen::Vector3d du = du_mm.segment<3>(3 * node);
    sliding.project(node, du);
    u_mm.segment<3>(3 * node) += du;
  }
}

}  // namespace ultrasim::sim
