#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/sim/probe_collider.hpp"

namespace ultrasim::sim {

struct SkinSettings {
  double spacing_mm = 4.0;  // grid step of the skin's nodes: the view's, coarse (CPU-drawn)
  double margin_mm = 16.0;  // how far the skin reaches beyond the simulated tissue, each side
  // Springs along the triangles' edges (the skin's own stiffness), and zero-length springs
  // holding each node to its rest place (the tissue under the skin, as published), N/mm.
  double edge_stiffness_n_per_mm = 0.05;
  double anchor_stiffness_n_per_mm = 0.01;
  double damping_per_s = 40.0;  // velocity damping
  double node_mass_g = 4.0;     // with the stiffness and substeps: stable (h·ω ≈ 1 < 2)
  int substeps_per_frame = 5;
};

// The skin over the body part, as published: its own mass-spring surface, anchored to its rest
// shape by zero-length springs and struck by the probe collider, so it dents under the probe and
// springs back when the probe lifts. Over the simulated tissue it does not move by itself: those
// nodes ("driven") are set to the deformed tissue's surface each frame, and the free skin around
// them is pulled along by its springs, so no seam shows where the skin crosses the tissue's edge.
//
// A flat grid at depth skin_z_mm (patient +z into the tissue) over the tissue's footprint grown
// by margin_mm; two triangles a cell, counter-clockwise seen from outside (−z).
class SkinSurface {
 public:
  // `footprint_min_mm`/`max`: the tissue's extent in x and y. Throws std::invalid_argument for
  // a footprint or settings out of range. Allocates.
  SkinSurface(const Eigen::Vector2d& footprint_min_mm, const Eigen::Vector2d& footprint_max_mm,
              double skin_z_mm, const SkinSettings& settings = {});

  int node_count() const { return static_cast<int>(rest_.size()); }
  // Nodes over the tissue, which step() takes from the caller.
  std::span<const std::int32_t> driven_nodes() const { return driven_; }
  std::span<const Eigen::Vector3d> rest_positions_mm() const { return rest_; }
  std::span<const Eigen::Vector3d> positions_mm() const { return position_; }
  std::span<const std::uint32_t> triangles() const { return triangles_; }

  // One frame of dt_s: the driven nodes placed at driven_positions_mm (driven_nodes() order),
  // the free ones integrated (semi-implicit Euler, substeps_per_frame substeps for a 60 Hz frame
  // or less, proportionally more for a longer dt_s, which the caller bounds: a frame the view
  // skipped) and pushed out of the probe (null:
  // no probe in reach). Never allocates. A non-finite input is refused (false, nothing changes);
  // a step that went non-finite puts the skin back at rest (false): never garbage on screen.
  bool step(const ProbeCollider* probe, std::span<const Eigen::Vector3d> driven_positions_mm,
            double dt_s);

  // The deepest dent below the rest surface, mm (0 at rest).
  double max_dent_mm() const;

 private:
  SkinSettings settings_;
  std::vector<Eigen::Vector3d> rest_, position_, velocity_, force_;
  std::vector<std::array<std::int32_t, 2>> edges_;
  std::vector<double> edge_rest_mm_;
  std::vector<std::uint8_t> is_driven_;
  std::vector<std::int32_t> driven_;
  std::vector<std::uint32_t> free_;  // the nodes not driven, which the springs move
  std::vector<std::uint32_t> triangles_;
};

}  // namespace ultrasim::sim
