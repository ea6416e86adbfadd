#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace ultrasim::hal {

// One square fiducial fixed to a rigid body: its id in the marker family and its four corners in
// the body's frame (mm), in the order a detector reports them: bottom-left, bottom-right,
// top-right, top-left as the marker is printed (AprilTag's order; OpenCV's SOLVEPNP_IPPE_SQUARE
// order once the tag frame's y points up).
struct BodyMarker {
  int id = 0;
  std::array<Eigen::Vector3d, 4> corners_mm;
  Eigen::Vector3d outward_normal = Eigen::Vector3d::UnitZ();  // unit, out of the body
};

// A rigid body carrying markers (the probe's dodecahedron, the published cube): what a camera
// tracker fits its detections to. Its frame's origin is the body's centre.
struct MarkerBody {
  std::string name;    // "dodecahedron", "cube"
  std::string family;  // the marker family, as the detector names it ("tag36h11")
  std::vector<BodyMarker> markers;
};

}  // namespace ultrasim::hal
