#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/volume.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

// Each tet's material from the label volume: the label at its centroid, or (kReuss) the Reuss
// average of the labels at the 84 points of a barycentric lattice through it (6 divisions per
// edge; sim::reuss_average).
// `materials` holds one entry per label; a label found in the mesh without one throws CaseError
// naming `source` and the label. Allocates; start-up only.
std::vector<sim::Material> tet_materials(const geometry::TetMesh& mesh,
                                         const imaging::Volume<std::uint8_t>& labels,
                                         std::span<const sim::Material> materials,
                                         sim::MaterialMixing mixing, const std::string& source);

}  // namespace ultrasim::kiosk
