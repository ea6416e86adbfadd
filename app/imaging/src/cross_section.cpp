#include "ultrasim/imaging/cross_section.hpp"

#include <cmath>

namespace ultrasim::imaging {

double deformed_label_area_mm2(const Volume<std::uint8_t>& labels, const geometry::TetMesh& mesh,
                               const geometry::TetLocator& deformed_locator,
                               const PlaneRegion& region, std::uint8_t label) {
  const int nu = static_cast<int>(std::floor(region.extent_u_mm / region.step_mm)) + 1;
  const int nv = static_cast<int>(std::floor(region.extent_v_mm / region.step_mm)) + 1;
  long count = 0;
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const Eigen::Vector3d p =
          region.origin_mm + (i * region.step_mm) * region.u + (j * region.step_mm) * region.v;
      const auto where = deformed_locator.locate(p);
      if (!where) continue;
      const auto& tet = mesh.tets[where->tet];
      Eigen::Vector3d rest = Eigen::Vector3d::Zero();
      for (int k = 0; k < 4; ++k) rest += where->barycentric[k] * mesh.rest_positions_mm[tet[k]];
      count += labels.sample_nearest(rest, 0) == label;
    }
  }
  return static_cast<double>(count) * region.step_mm * region.step_mm;
}

}  // namespace ultrasim::imaging
