#include "ultrasim/sim/skin_surface.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace ultrasim::sim {

SkinSurface::SkinSurface(const Eigen::Vector2d& footprint_min_mm,
                         const Eigen::Vector2d& footprint_max_mm, double skin_z_mm,
                         const SkinSettings& settings)
    : settings_(settings) {
  if (!(settings.spacing_mm > 0.0) || !(settings.margin_mm >= 0.0) ||
      !(settings.edge_stiffness_n_per_mm > 0.0) || !(settings.anchor_stiffness_n_per_mm >= 0.0) ||
      !(settings.damping_per_s >= 0.0) || !(settings.node_mass_g > 0.0) ||
      settings.substeps_per_frame < 1) {
    throw std::invalid_argument(
        "skin: spacing, stiffness and mass must be > 0, margin, anchor "
        "stiffness and damping >= 0, substeps >= 1");
  }
  if (!(footprint_max_mm.array() > footprint_min_mm.array()).all()) {
    throw std::invalid_argument("skin: the tissue's footprint is empty");
  }
  const Eigen::Vector2d lo = footprint_min_mm.array() - settings.margin_mm;
  const Eigen::Vector2d hi = footprint_max_mm.array() + settings.margin_mm;
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / settings.spacing_mm)) + 1;
  const int ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / settings.spacing_mm)) + 1;
  const auto at = [nx](int i, int j) { return j * nx + i; };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const Eigen::Vector3d p(lo.x() + i * settings.spacing_mm, lo.y() + j * settings.spacing_mm,
                              skin_z_mm);
      rest_.push_back(p);
      // Over the tissue (its boundary included): taken from the tissue's surface.
      const bool over =
          p.x() >= footprint_min_mm.x() - 1e-9 && p.x() <= footprint_max_mm.x() + 1e-9 &&
          p.y() >= footprint_min_mm.y() - 1e-9 && p.y() <= footprint_max_mm.y() + 1e-9;
      is_driven_.push_back(over);
      if (over) driven_.push_back(at(i, j));
    }
  }
  for (int j = 0; j + 1 < ny; ++j) {
    for (int i = 0; i + 1 < nx; ++i) {
      const auto a = static_cast<std::uint32_t>(at(i, j)),
                 b = static_cast<std::uint32_t>(at(i + 1, j));
      const auto c = static_cast<std::uint32_t>(at(i + 1, j + 1)),
                 d = static_cast<std::uint32_t>(at(i, j + 1));
      // Seen from −z (outside, above the skin) with x right and y down the page: a, d, c and
      // a, c, b run counter-clockwise.
      triangles_.insert(triangles_.end(), {a, d, c, a, c, b});
    }
  }
  // Springs: grid edges and one diagonal a cell (the triangles' edges), and the other diagonal
  // too, so a sheet resists shear the same both ways. A spring between two driven nodes moves
  // nothing (their places come from the tissue), so only springs with a free end are kept: over
  // a large tissue most of the skin is driven.
  const auto add_edge = [&](int a, int b) {
    if (!is_driven_[static_cast<std::size_t>(a)] || !is_driven_[static_cast<std::size_t>(b)]) {
      edges_.push_back({a, b});
    }
  };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (i + 1 < nx) add_edge(at(i, j), at(i + 1, j));
      if (j + 1 < ny) add_edge(at(i, j), at(i, j + 1));
      if (i + 1 < nx && j + 1 < ny) {
        add_edge(at(i, j), at(i + 1, j + 1));
        add_edge(at(i + 1, j), at(i, j + 1));
      }
    }
  }
  for (const auto& e : edges_) edge_rest_mm_.push_back((rest_[e[0]] - rest_[e[1]]).norm());
  for (std::size_t n = 0; n < rest_.size(); ++n) {
    if (!is_driven_[n]) free_.push_back(static_cast<std::uint32_t>(n));
  }
  position_ = rest_;
  velocity_.assign(rest_.size(), Eigen::Vector3d::Zero());
  force_.assign(rest_.size(), Eigen::Vector3d::Zero());
}

bool SkinSurface::step(const ProbeCollider* probe,
                       std::span<const Eigen::Vector3d> driven_positions_mm, double dt_s) {
  if (driven_positions_mm.size() != driven_.size() || !(dt_s > 0.0)) return false;
  for (const auto& p : driven_positions_mm) {
    if (!p.allFinite()) return false;
  }
  for (std::size_t k = 0; k < driven_.size(); ++k) {
    position_[static_cast<std::size_t>(driven_[k])] = driven_positions_mm[k];
    velocity_[static_cast<std::size_t>(driven_[k])].setZero();
    // Its springs' pulls add up over the frame's substeps, unread: bounded, not carried over.
    force_[static_cast<std::size_t>(driven_[k])].setZero();
  }
  // The settings' substeps keep a 60 Hz frame stable; a longer step takes as many more.
  constexpr double kDesignFrameS = 1.0 / 60.0;
  const int substeps = std::max(
      settings_.substeps_per_frame,
      static_cast<int>(std::ceil(dt_s / kDesignFrameS * settings_.substeps_per_frame - 1e-9)));
  const double h = dt_s / substeps;
  const double mass_kg = settings_.node_mass_g * 1e-3;
  // N/mm on mm gives N; over kg gives m/s², which is 1000 mm/s².
  const double accel_mm_per_n = 1e3 / mass_kg;
  // Only a node inside the probe's box can be inside the probe: the box spares most nodes the
  // distance query (the large case's 560 free nodes five times a frame: ~0.1 ms of the view).
  Eigen::AlignedBox3d probe_box;
  probe_box.setEmpty();  // holds no point
  if (probe != nullptr) probe_box = probe->bounds_mm();
  for (int s = 0; s < substeps; ++s) {
    // Only the free nodes move: a driven node's force is never read.
    for (const std::uint32_t n : free_) {
      force_[n] = settings_.anchor_stiffness_n_per_mm * (rest_[n] - position_[n]);
    }
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      const auto a = static_cast<std::size_t>(edges_[e][0]);
      const auto b = static_cast<std::size_t>(edges_[e][1]);
      const Eigen::Vector3d d = position_[b] - position_[a];
      const double length = d.norm();
      if (length < 1e-12) continue;
      const Eigen::Vector3d f =
          settings_.edge_stiffness_n_per_mm * (length - edge_rest_mm_[e]) / length * d;
      force_[a] += f;
      force_[b] -= f;
    }
    const double keep = 1.0 / (1.0 + settings_.damping_per_s * h);
    for (const std::uint32_t n : free_) {
      velocity_[n] = keep * (velocity_[n] + h * accel_mm_per_n * force_[n]);
      position_[n] += h * velocity_[n];
      // The probe cannot be entered: a node inside it goes down the beam to the face (the skin
      // is pressed, not pushed sideways), or where that is not out, to the nearest surface.
      if (probe_box.contains(position_[n]) && probe->signed_distance_mm(position_[n]) < 0.0) {
        const Eigen::Vector3d beam = probe->beam_axis();
        const double to_face = (probe->face_center_mm() - position_[n]).dot(beam);
        Eigen::Vector3d out = position_[n] + std::max(to_face, 0.0) * beam;
        if (probe->signed_distance_mm(out) < -1e-6) {
          out = probe->closest_surface_point(out).point_mm;
        }
        position_[n] = out;
        velocity_[n].setZero();
      }
    }
  }
  for (const auto& p : position_) {
    if (!p.allFinite()) {
      position_ = rest_;  // never show garbage; start again from rest
      for (auto& v : velocity_) v.setZero();
      return false;
    }
  }
  return true;
}

double SkinSurface::max_dent_mm() const {
  double dent = 0.0;
  for (std::size_t n = 0; n < rest_.size(); ++n) {
    dent = std::max(dent, position_[n].z() - rest_[n].z());
  }
  return dent;
}

}  // namespace ultrasim::sim
