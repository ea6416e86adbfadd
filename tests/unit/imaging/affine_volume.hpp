#pragma once

// A test volume whose echo is an affine function of position with whole-number values on its
// voxel grid (1 mm spacing, integer origin), so the stored bytes are exact, trilinear sampling is
// exact, and every slicer's expected grey level is known to within the final rounding (±0.5).

#include <cmath>
#include <cstdint>

#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging::testing {

inline double affine_echo(const Eigen::Vector3d& p) {
  return 60.0 + 2.0 * p.x() + p.y() + 3.0 * p.z();
}

// 41×21×31 voxels from (-20, -10, 0) mm: echo 10..200 over it.
inline Volume<std::uint8_t> affine_volume() {
  Volume<std::uint8_t> v({41, 21, 31}, {1.0, 1.0, 1.0}, {-20.0, -10.0, 0.0});
  for (int k = 0; k < 31; ++k)
    for (int j = 0; j < 21; ++j)
      for (int i = 0; i < 41; ++i)
        v.at(i, j, k) = static_cast<std::uint8_t>(
            std::lround(affine_echo(v.index_to_world({double(i), double(j), double(k)}))));
  return v;
}

inline constexpr double kRoundingTolerance = 0.5 + 1e-6;

}  // namespace ultrasim::imaging::testing
