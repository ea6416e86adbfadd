#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging {

// A rectangle in the patient: origin + s·u + t·v for s in [0, extent_u_mm], t in [0, extent_v_mm]
// (u, v orthonormal), sampled every step_mm.
struct PlaneRegion {
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v = Eigen::Vector3d::UnitZ();
  double extent_u_mm = 0.0;
  double extent_v_mm = 0.0;
  double step_mm = 0.25;
};

// Area (mm²) that tissue of `label` covers in a plane region of the deformed tissue: each sample
// point is located in the deformed mesh, mapped back to its rest position by the tet's barycentric
// coordinates, and the label volume read there (nearest voxel). A vessel's lumen area in the
// B-scan plane, measured from the labels rather than the echoes. `deformed_locator` must be
// rebuilt on the deformed positions; `mesh` gives the rest positions. Does not allocate.
double deformed_label_area_mm2(const Volume<std::uint8_t>& labels, const geometry::TetMesh& mesh,
                               const geometry::TetLocator& deformed_locator,
                               const PlaneRegion& region, std::uint8_t label);

}  // namespace ultrasim::imaging
