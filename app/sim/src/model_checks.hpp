#pragma once

// Input checks every deformation engine shares (private to app/sim).

#include <cstdint>
#include <span>
#include <string_view>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// Throws std::invalid_argument unless E > 0 (finite) and ν in [0, 0.5), naming the material.
void check_material(const Material& m);

// Throws std::invalid_argument, prefixed with `engine`, unless there is one material per tet and
// one fixed flag per node, at least one node is fixed (else the stiffness is singular), every tet
// references nodes of the mesh and has positive rest volume, and every material is physical.
// Returns the number of fixed nodes.
int check_tet_model(std::string_view engine, const geometry::TetMesh& mesh,
                    std::span<const Material> tet_materials,
                    std::span<const std::uint8_t> fixed_nodes);

// Throws std::invalid_argument, prefixed with `engine`, unless the friction coefficient is finite
// and ≥ 0.
void check_held_contact_settings(const HeldContactSettings& s, std::string_view engine);

}  // namespace ultrasim::sim
