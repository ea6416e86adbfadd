#pragma once

#include <Eigen/Core>

namespace ultrasim::sim {

// The published probe collider: a sphere whose lowest point (along the beam) is the centre of the
// transducer face. Mesh nodes found inside it are pushed out radially to its surface.
struct SphereCollider {
  Eigen::Vector3d center_mm = Eigen::Vector3d::Zero();
  double radius_mm = 30.0;

  // Sphere resting on the probe face: centre radius_mm behind the face along the beam axis.
  static SphereCollider behind_face(const Eigen::Vector3d& face_center_mm,
                                    const Eigen::Vector3d& beam_axis, double radius_mm) {
    return SphereCollider{face_center_mm - radius_mm * beam_axis.normalized(), radius_mm};
  }
};

}  // namespace ultrasim::sim
