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

// Coulomb's law for a node the probe holds on its surface at `held` (HeldContactModel::
// kCoulombSlip). `tissue_force_mn` is the tissue's elastic force on the node there and
// `stiffness` the node's own 3 × 3 block of the tissue's stiffness (how that force changes as the
// node alone moves, mN/mm). The node sticks (`held` comes back) while the tissue pushes it against
// the probe and pulls it along the surface no harder than `friction_coefficient` × that push, or
// when it pulls it off the probe (letting go is the caller's rule). Otherwise it slides along the
// surface the way it is pulled, as far as brings the pull down to the bound to first order (at
// most kMaxSlidePerStepMm), and comes back on the surface there. Called on each held node in turn
// after a step's contacts are placed, each with its neighbours where the earlier calls put them,
// it relaxes the contact patch towards Coulomb's equilibrium step by step (Gauss-Seidel), as the
// probe slides.
SurfacePoint slide_held_node(const ProbeCollider& probe, const SurfacePoint& held,
                             const Eigen::Vector3d& tissue_force_mn,
                             const Eigen::Matrix3d& stiffness, double friction_coefficient);

// Coulomb's law for a solver that slides held nodes inside its own solve (the PCG and
// corotational FEM's filtered CG): a node the probe holds at a point with outward `normal`, where
// the tissue's elastic force on it is `tissue_force_mn`, sticks (held in all three axes) while
// the tissue pulls it along the surface no harder than `friction_coefficient` × its push against
// the probe; otherwise it is held along the normal only and slides in the tangent plane against a
// friction force of that bound, opposite the pull (`friction_mn`, added to its load).
// Frictionless, every held node slides; so does one the tissue pulls off the probe (no push, no
// friction: letting go of it is the engine's rule). A force that is not finite sticks.
struct HeldNodeLaw {
  bool slides = false;
  Eigen::Vector3d friction_mn = Eigen::Vector3d::Zero();
};
HeldNodeLaw coulomb_hold(const Eigen::Vector3d& normal, const Eigen::Vector3d& tissue_force_mn,
                         double friction_coefficient);

// The first-order slide is exact on a flat face; on the rounded rim the surface turns away within
// the edge radius, so one step moves a node no farther than this and the next step goes on.
inline constexpr double kMaxSlidePerStepMm = 1.0;

}  // namespace ultrasim::sim
