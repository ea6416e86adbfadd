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
// average of the labels at kTetSamples points spread evenly through it (sim::reuss_average).
// `materials` holds one entry per label; a label found in the mesh without one throws CaseError
// naming `source` and the label. Allocates; start-up only.
std::vector<sim::Material> tet_materials(const geometry::TetMesh& mesh,
                                         const imaging::Volume<std::uint8_t>& labels,
                                         std::span<const sim::Material> materials,
                                         sim::MaterialMixing mixing, const std::string& source);

// Points a tet is sampled at for kReuss: the barycentric lattice with 6 divisions per edge.
inline constexpr int kTetSampleDivisions = 6;
inline constexpr int kTetSamples = 84;  // (n + 1)(n + 2)(n + 3) / 6

}  // namespace ultrasim::kiosk
