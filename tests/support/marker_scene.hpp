#pragma once

// The fiducial tests' camera and motion; the views themselves are drawn by
// ultrasim-camera-views's marker_body_mesh (app/tools/camera_views).

#include <Eigen/Geometry>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/tools/marker_mesh.hpp"

namespace ultrasim::test {

using tools::camera_frame;
using tools::marker_body_mesh;

// The 640 × 480 camera of the tests: 600 px focal length (a 56° horizontal field).
inline hal::CameraIntrinsics test_camera() {
  hal::CameraIntrinsics c;
  c.fx_px = c.fy_px = 600.0;
  c.cx_px = 319.5;
  c.cy_px = 239.5;
  return c;
}

// A hand's sweep through every orientation: `frames` poses at 60 Hz (4 s for 240) turning the
// body once about a tilted axis and half a turn about the camera's axis while it circles in
// the image, 0.3–0.4 m away: about 90°/s and 150 mm/s.
inline std::vector<Eigen::Isometry3d> sweep_poses(int frames) {
  constexpr double kPi = 3.14159265358979323846;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < frames; ++i) {
    const double t = static_cast<double>(i) / frames;
    const Eigen::Vector3d centre(60.0 * std::cos(2 * kPi * t), 40.0 * std::sin(2 * kPi * t),
                                 350.0 + 50.0 * std::sin(4 * kPi * t));
    poses.push_back(Eigen::Translation3d(centre) *
                    Eigen::AngleAxisd(kPi * t, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(2 * kPi * t, Eigen::Vector3d(1.0, 1.0, 0.3).normalized()));
  }
  return poses;
}

}  // namespace ultrasim::test
