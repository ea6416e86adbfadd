#include "model_checks.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace ultrasim::sim {

void check_material(const Material& m) {
  if (!(m.youngs_modulus_kpa > 0) || !std::isfinite(m.youngs_modulus_kpa)) {
    throw std::invalid_argument("material '" + m.name + "': youngs_modulus_kpa must be > 0");
  }
  if (!(m.poisson_ratio >= 0.0 && m.poisson_ratio < 0.5)) {
    throw std::invalid_argument("material '" + m.name + "': poisson_ratio must be in [0, 0.5)");
  }
}

void check_held_contact_settings(const HeldContactSettings& s, std::string_view engine) {
  if (!(s.friction_coefficient >= 0.0) || !std::isfinite(s.friction_coefficient)) {
    throw std::invalid_argument(std::string(engine) +
                                ": contact friction_coefficient must be finite and >= 0");
  }
}

int check_tet_model(std::string_view engine, const geometry::TetMesh& mesh,
                    std::span<const Material> tet_materials,
                    std::span<const std::uint8_t> fixed_nodes) {
  const std::string prefix = std::string(engine) + ": ";
  const int n = mesh.node_count();
  if (tet_materials.size() != mesh.tets.size()) {
    throw std::invalid_argument(prefix + "need one material per tet (" +
                                std::to_string(tet_materials.size()) + " for " +
                                std::to_string(mesh.tets.size()) + " tets)");
  }
  if (fixed_nodes.size() != static_cast<std::size_t>(n)) {
    throw std::invalid_argument(prefix + "need one fixed flag per node (" +
                                std::to_string(fixed_nodes.size()) + " for " + std::to_string(n) +
                                " nodes)");
  }
  int fixed = 0;
  for (auto f : fixed_nodes) fixed += f != 0;
  if (fixed == 0) {
    throw std::invalid_argument(
        prefix +
        "no fixed nodes: the stiffness matrix is singular (the tissue could float away); fix a "
        "face or a label in the case's [mesh] table");
  }
  const auto& p = mesh.rest_positions_mm;
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& tet = mesh.tets[t];
    for (auto node : tet) {
      if (node < 0 || node >= n) {
        throw std::invalid_argument(prefix + "tet " + std::to_string(t) + " references node " +
                                    std::to_string(node) + " outside the mesh");
      }
    }
    if (!(geometry::signed_tet_volume(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) > 0.0)) {
      throw std::invalid_argument(prefix + "tet " + std::to_string(t) + " has no positive volume");
    }
    check_material(tet_materials[t]);
  }
  return fixed;
}

}  // namespace ultrasim::sim
