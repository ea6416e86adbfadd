#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ultrasim/sim/sphere_collider.hpp"

namespace ultrasim::sim {

// A point on the probe's surface and the probe's outward normal there (pointing into the tissue).
struct SurfacePoint {
  Eigen::Vector3d point_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
};

// The rigid probe as the tissue feels it: a solid whose surface the tissue may touch but not
// enter. Three shapes, all placed by the transducer face's centre and the probe's orientation
// (columns: lateral x, elevation y, beam z pointing into the tissue):
//   - sphere: the published collider, its lowest point at the face centre;
//   - linear face: a box with rounded edges, the transducer face flat at the face centre, the
//     body extending behind it (against the beam);
//   - convex face: a cylinder section, its axis along elevation, the face an arc through the
//     face centre, with rounded rims.
// A value type: copy it freely; every query is a few flops and allocates nothing.
class ProbeCollider {
 public:
  enum class Shape { kSphere, kLinearFace, kConvexFace };

  // The published sphere collider; `beam_axis` only locates the face (the sphere's lowest point).
  static ProbeCollider sphere(const SphereCollider& s,
                              const Eigen::Vector3d& beam_axis = Eigen::Vector3d::UnitZ());
  // Linear transducer: face width (lateral) × thickness (elevation), edges rounded with
  // `edge_radius_mm` (≤ half the thickness), body `body_length_mm` long behind the face.
  static ProbeCollider linear_face(const Eigen::Vector3d& face_center_mm,
                                   const Eigen::Quaterniond& orientation, double width_mm,
                                   double thickness_mm, double edge_radius_mm,
                                   double body_length_mm = 80.0);
  // Convex transducer: face arc of radius `face_radius_mm` about an axis along elevation,
  // thickness (elevation) with rims rounded by `edge_radius_mm`.
  static ProbeCollider convex_face(const Eigen::Vector3d& face_center_mm,
                                   const Eigen::Quaterniond& orientation, double face_radius_mm,
                                   double thickness_mm, double edge_radius_mm);

  Shape shape() const { return shape_; }

  // Signed distance from p to the probe's surface, mm: negative inside the probe.
  double signed_distance_mm(const Eigen::Vector3d& p_mm) const;

  // The closest point on the surface to p and the outward normal there. For a point inside, the
  // point the published collider pushes it out to.
  SurfacePoint closest_surface_point(const Eigen::Vector3d& p_mm) const;

  // The smallest axis-aligned box holding the probe's solid (its rounding included, the linear
  // face's body too): a point outside it is outside the probe by at least its distance to the box.
  Eigen::AlignedBox3d bounds_mm() const;

  const Eigen::Vector3d& face_center_mm() const { return face_center_mm_; }
  Eigen::Vector3d beam_axis() const { return frame_.col(2); }

 private:
  // p in the probe frame: origin at the shape's reference centre.
  Eigen::Vector3d to_local(const Eigen::Vector3d& p_mm) const;

  Shape shape_ = Shape::kSphere;
  Eigen::Vector3d face_center_mm_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d frame_ = Eigen::Matrix3d::Identity();       // columns: lateral, elevation, beam
  Eigen::Vector3d center_mm_ = Eigen::Vector3d::Zero();       // sphere / box / cylinder centre
  double radius_mm_ = 30.0;                                   // sphere or cylinder radius
  Eigen::Vector3d half_extent_mm_ = Eigen::Vector3d::Zero();  // box: inner box half sizes
  double edge_radius_mm_ = 0.0;
};

}  // namespace ultrasim::sim
