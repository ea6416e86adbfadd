#pragma once

#include <Eigen/Geometry>
#include <array>
#include <vector>

#include "ultrasim/hal/marker_model.hpp"
#include "ultrasim/tracking/dodecahedron_net.hpp"

namespace ultrasim::tracking {

// An AprilTag tag36h11 image is 10 × 10 cells with a white outer ring; its detector reports the
// black border's corners, 8 cells across. The ring must be printed on the face: the detector
// reads it, and where a face's edge cut into it, tags on dimly lit faces went undetected.
inline constexpr double kTag36h11BorderFraction = 0.8;

// The side of the largest square marker (an AprilTag's white ring included) centred on a face
// of edge `edge_mm`, its top toward the face's "up", that stays 2 % inside the pentagon: what
// ultrasim-marker-select prints.
double largest_marker_side_mm(double edge_mm);

// Where each face of a folded net lies: the rigid map from the page (x, y in mm as printed,
// z = 0) to the solid's frame, whose origin is the solid's centre. Folded with the print
// outside, so a face seen from outside looks as it does on the page.
std::vector<Eigen::Isometry3d> fold_dodecahedron_net(const DodecahedronNet& net);

// The dodecahedron folded from make_dodecahedron_net(edge_mm) with tag36h11 ids 0–11 printed on
// faces 0–11 as ultrasim-marker-select prints them: `printed_side_mm` across (white ring
// included), centred, top row toward the face's "up". The markers' corners are the detected
// (black border) square's.
hal::MarkerBody dodecahedron_marker_body(double edge_mm, double printed_side_mm);

// The published cube: tag36h11 ids 0–5, one per face, `printed_side_mm` across (white ring
// included), centred.
hal::MarkerBody cube_marker_body(double edge_mm, double printed_side_mm);

// A rigid transform written as x, y, z (mm) then a rotation vector (axis × angle, degrees), as
// app.toml's [probe] camera_pose and probe_in_body give them.
Eigen::Isometry3d rigid_from_xyz_rotvec_deg(const std::array<double, 6>& values);

// The bodies' faces as polygons in the body's frame (mm), corners counter-clockwise seen from
// outside, in marker order: face i carries marker i. For drawing the bodies.
std::vector<std::vector<Eigen::Vector3d>> dodecahedron_faces(double edge_mm);
std::vector<std::vector<Eigen::Vector3d>> cube_faces(double edge_mm);

}  // namespace ultrasim::tracking
