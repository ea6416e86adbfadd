#pragma once

// The published MSDS with explicit Euler, written the obvious way: springs one by one in double,
// no layout, no SIMD, no shortcuts. The reference the engine's explicit integrator is checked
// against (msds_reference_test.cpp) and timed against (tests/bench/msds_bench.cpp).

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <map>
#include <span>
#include <utility>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/contact.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::testing {

class NaiveMsds {
 public:
  // The engine's contact tolerance (msds.cpp).
  static constexpr double kTouchToleranceMm = 1e-6;

  struct Spring {
    int a = 0, b = 0;
    double rest_length_mm = 0.0;
    double stiffness_mn_per_mm = 0.0;
    double damping_mn_s_per_mm = 0.0;
  };

  // Springs on the tets' edges (k = Σ E × stiffness_per_modulus_mm over the edge's tets, c = β k),
  // lumped masses (a quarter of each tet's volume × density), at rest.
  NaiveMsds(const geometry::TetMesh& mesh, std::span<const sim::Material> tet_materials,
            std::span<const std::uint8_t> fixed_nodes, const sim::MsdsSettings& s)
      : fixed(fixed_nodes.begin(), fixed_nodes.end()), x(mesh.rest_positions_mm) {
    const auto& p = mesh.rest_positions_mm;
    std::map<std::pair<int, int>, double> stiffness;
    mass_kg.assign(p.size(), 0.0);
    for (int t = 0; t < mesh.tet_count(); ++t) {
      const auto& tet = mesh.tets[t];
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) {
          stiffness[{std::min(tet[i], tet[j]), std::max(tet[i], tet[j])}] +=
              tet_materials[t].youngs_modulus_kpa * s.stiffness_per_modulus_mm;
        }
      }
      const double volume_mm3 =
          geometry::signed_tet_volume(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]);
      for (int n : tet) mass_kg[n] += 0.25 * volume_mm3 * s.density_kg_per_m3 * 1e-9;
    }
    for (const auto& [edge, k] : stiffness) {
      springs.push_back({edge.first, edge.second, (p[edge.second] - p[edge.first]).norm(), k,
                         k * s.damping_per_stiffness_s});
    }
    v.assign(p.size(), Eigen::Vector3d::Zero());
    force_.assign(p.size(), Eigen::Vector3d::Zero());
    held_.assign(p.size(), 0);
  }

  // One step: contacts (nodes inside the probe onto its surface, held at zero velocity), every
  // spring's elastic and damping force, the release of touching nodes pulled away, forward Euler.
  void step(double dt_s, const sim::ProbeCollider* probe) {
    const int n = static_cast<int>(x.size());
    contacts_.clear();
    if (probe != nullptr) {
      sim::find_contacts(*probe, x, fixed, kTouchToleranceMm, contacts_);
    }
    std::fill(held_.begin(), held_.end(), 0);
    for (const auto& c : contacts_) {
      x[c.node] = c.target_mm;
      v[c.node].setZero();
      held_[c.node] = 1;
    }
    std::fill(force_.begin(), force_.end(), Eigen::Vector3d::Zero());
    for (const Spring& s : springs) {
      const Eigen::Vector3d d = x[s.b] - x[s.a];
      const double length = d.norm();
      const Eigen::Vector3d dir = d / length;
      const Eigen::Vector3d f = s.stiffness_mn_per_mm * (length - s.rest_length_mm) * dir +
                                s.damping_mn_s_per_mm * (v[s.b] - v[s.a]).dot(dir) * dir;
      force_[s.a] += f;
      force_[s.b] -= f;
    }
    for (const auto& c : contacts_) {
      if (c.depth_mm <= kTouchToleranceMm && force_[c.node].dot(c.normal) > 0.0) held_[c.node] = 0;
    }
    held_nodes = static_cast<int>(std::count(held_.begin(), held_.end(), 1));
    for (int i = 0; i < n; ++i) {
      if (fixed[i] || held_[i]) continue;
      x[i] += dt_s * v[i];
      v[i] += dt_s / mass_kg[i] * force_[i];
    }
  }

  std::vector<Spring> springs;
  std::vector<double> mass_kg;
  std::vector<std::uint8_t> fixed;
  std::vector<Eigen::Vector3d> x, v;
  int held_nodes = 0;  // after the last step

 private:
  // Scratch, kept so that a step's time is its arithmetic, not its allocations.
  std::vector<sim::NodeContact> contacts_;
  std::vector<std::uint8_t> held_;
  std::vector<Eigen::Vector3d> force_;
};

}  // namespace ultrasim::testing
