#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "ultrasim/imaging/bscan.hpp"

namespace ultrasim::imaging {

// One frame's image plane as an affine map between pixel coordinates and patient space: pixel
// (col, row) has its centre at (col, row), so whole numbers are the sample points the reference
// slicer uses (BscanGrid::pixel_to_plane_mm, then ProbePose::to_patient). Private to the slicers:
// they turn per-tet maps into maps of pixel coordinates with it. Plain value; no allocation.
struct PixelPlane {
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();    // centre of pixel (0, 0)
  Eigen::Vector3d per_col_mm = Eigen::Vector3d::UnitX();  // step to the next column
  Eigen::Vector3d per_row_mm = Eigen::Vector3d::UnitZ();  // step to the next row (deeper)
  Eigen::Vector3d unit_normal = Eigen::Vector3d::UnitY();
  // (col, row) of a point of the plane, relative to origin_mm; the pseudo-inverse of
  // [per_col per_row], so the probe axes need not be orthonormal, only independent.
  Eigen::Matrix<double, 2, 3> to_pixel = Eigen::Matrix<double, 2, 3>::Zero();

  static PixelPlane of(const BscanGrid& grid, const ProbePose& pose) {
    const ImageExtent& e = grid.extent();
    const double col_mm = e.width_mm() / grid.width_px();
    const double row_mm = e.depth_mm() / grid.height_px();
    PixelPlane plane;
    plane.origin_mm = pose.to_patient({e.x_min_mm + 0.5 * col_mm, e.z_min_mm + 0.5 * row_mm});
    plane.per_col_mm = pose.axes.col(0) * col_mm;
    plane.per_row_mm = pose.axes.col(2) * row_mm;
    plane.unit_normal = plane.per_col_mm.cross(plane.per_row_mm).normalized();
    Eigen::Matrix<double, 3, 2> m;
    m << plane.per_col_mm, plane.per_row_mm;
    plane.to_pixel = (m.transpose() * m).inverse() * m.transpose();
    return plane;
  }

  Eigen::Vector2d pixel_of(const Eigen::Vector3d& p_mm) const {
    return to_pixel * (p_mm - origin_mm);
  }
};

}  // namespace ultrasim::imaging
