#include "ultrasim/sim/probe_collider.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ultrasim::sim {

namespace {

void require_positive(const char* what, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string("ProbeCollider: ") + what + " must be > 0");
  }
}

Eigen::Matrix3d frame_of(const Eigen::Quaterniond& orientation) {
  return orientation.normalized().toRotationMatrix();
}

}  // namespace

ProbeCollider ProbeCollider::sphere(const SphereCollider& s, const Eigen::Vector3d& beam_axis) {
  require_positive("sphere radius", s.radius_mm);
  ProbeCollider c;
  c.shape_ = Shape::kSphere;
  c.center_mm_ = s.center_mm;
  c.radius_mm_ = s.radius_mm;
  c.frame_.col(2) = beam_axis.normalized();
  c.face_center_mm_ = s.center_mm + s.radius_mm * c.frame_.col(2);
  return c;
}

ProbeCollider ProbeCollider::linear_face(const Eigen::Vector3d& face_center_mm,
                                         const Eigen::Quaterniond& orientation, double width_mm,
                                         double thickness_mm, double edge_radius_mm,
                                         double body_length_mm) {
  require_positive("face width", width_mm);
  require_positive("face thickness", thickness_mm);
  require_positive("body length", body_length_mm);
  const double half_min = 0.5 * std::min({width_mm, thickness_mm, body_length_mm});
  if (!(edge_radius_mm >= 0.0 && edge_radius_mm < half_min)) {
    throw std::invalid_argument(
        "ProbeCollider: edge radius must be >= 0 and below half the smallest face size");
  }
  ProbeCollider c;
  c.shape_ = Shape::kLinearFace;
  c.face_center_mm_ = face_center_mm;
  c.frame_ = frame_of(orientation);
  c.center_mm_ = face_center_mm - 0.5 * body_length_mm * c.frame_.col(2);
  c.half_extent_mm_ = 0.5 * Eigen::Vector3d(width_mm, thickness_mm, body_length_mm) -
                      Eigen::Vector3d::Constant(edge_radius_mm);
  c.edge_radius_mm_ = edge_radius_mm;
  c.radius_mm_ = 0.5 * width_mm;
  return c;
}

ProbeCollider ProbeCollider::convex_face(const Eigen::Vector3d& face_center_mm,
                                         const Eigen::Quaterniond& orientation,
                                         double face_radius_mm, double thickness_mm,
                                         double edge_radius_mm) {
  require_positive("face radius", face_radius_mm);
  require_positive("face thickness", thickness_mm);
  if (!(edge_radius_mm >= 0.0 && edge_radius_mm < 0.5 * std::min(thickness_mm, face_radius_mm))) {
    throw std::invalid_argument(
        "ProbeCollider: edge radius must be >= 0 and below half the face thickness");
  }
  ProbeCollider c;
  c.shape_ = Shape::kConvexFace;
  c.face_center_mm_ = face_center_mm;
  c.frame_ = frame_of(orientation);
  c.center_mm_ = face_center_mm - face_radius_mm * c.frame_.col(2);
  c.radius_mm_ = face_radius_mm;
  // Inner solid (the cylinder shrunk by the rounding): x = radius, y = half length.
  c.half_extent_mm_ =
      Eigen::Vector3d(face_radius_mm - edge_radius_mm, 0.5 * thickness_mm - edge_radius_mm, 0.0);
  c.edge_radius_mm_ = edge_radius_mm;
  return c;
}

Eigen::Vector3d ProbeCollider::to_local(const Eigen::Vector3d& p_mm) const {
  return frame_.transpose() * (p_mm - center_mm_);
}

double ProbeCollider::signed_distance_mm(const Eigen::Vector3d& p_mm) const {
  if (shape_ == Shape::kSphere) return (p_mm - center_mm_).norm() - radius_mm_;
  const SurfacePoint s = closest_surface_point(p_mm);
  return (p_mm - s.point_mm).dot(s.normal);
}

SurfacePoint ProbeCollider::closest_surface_point(const Eigen::Vector3d& p_mm) const {
  SurfacePoint out;
  if (shape_ == Shape::kSphere) {
    const Eigen::Vector3d d = p_mm - center_mm_;
    const double r = d.norm();
    // The centre itself has no direction: push it along the beam, as the tissue sees the probe.
    out.normal = r > 1e-12 ? Eigen::Vector3d(d / r) : Eigen::Vector3d::UnitZ();
    out.point_mm = center_mm_ + radius_mm_ * out.normal;
    return out;
  }
  const Eigen::Vector3d p = to_local(p_mm);
  Eigen::Vector3d inner_point;  // closest point of the inner (unrounded) solid, local
  Eigen::Vector3d normal;       // local
  if (shape_ == Shape::kLinearFace) {
    const Eigen::Vector3d h = half_extent_mm_;
    const Eigen::Vector3d clamped = p.cwiseMax(-h).cwiseMin(h);
    const Eigen::Vector3d v = p - clamped;
    if (v.squaredNorm() > 0.0) {
      inner_point = clamped;
      normal = v.normalized();
    } else {
      // Inside the inner box: leave through the nearest face.
      const Eigen::Vector3d gap = h - p.cwiseAbs();
      int axis = 0;
      gap.minCoeff(&axis);
      normal = Eigen::Vector3d::Zero();
      normal[axis] = p[axis] < 0.0 ? -1.0 : 1.0;
      inner_point = p;
      inner_point[axis] = normal[axis] * h[axis];
    }
  } else {
    // Cylinder along local y; radial in the x-z plane.
    const double radius = half_extent_mm_.x(), half_length = half_extent_mm_.y();
    const Eigen::Vector2d radial(p.x(), p.z());
    const double rho = radial.norm();
    const Eigen::Vector2d dir = rho > 1e-12 ? Eigen::Vector2d(radial / rho) : Eigen::Vector2d(0, 1);
    const double rho_c = std::min(rho, radius);
    const double y_c = std::clamp(p.y(), -half_length, half_length);
    const Eigen::Vector3d clamped(dir.x() * rho_c, y_c, dir.y() * rho_c);
    const Eigen::Vector3d v = p - clamped;
    if (v.squaredNorm() > 0.0) {
      inner_point = clamped;
      normal = v.normalized();
    } else if (radius - rho <= half_length - std::abs(p.y())) {
      normal = Eigen::Vector3d(dir.x(), 0.0, dir.y());
      inner_point = Eigen::Vector3d(dir.x() * radius, p.y(), dir.y() * radius);
    } else {
      normal = Eigen::Vector3d(0.0, p.y() < 0.0 ? -1.0 : 1.0, 0.0);
      inner_point = Eigen::Vector3d(p.x(), normal.y() * half_length, p.z());
    }
  }
  out.normal = frame_ * normal;
  out.point_mm = center_mm_ + frame_ * (inner_point + edge_radius_mm_ * normal);
  return out;
}

Eigen::AlignedBox3d ProbeCollider::bounds_mm() const {
  Eigen::Vector3d half;  // the solid's half extent along each world axis
  if (shape_ == Shape::kSphere) {
    half.setConstant(radius_mm_);
  } else if (shape_ == Shape::kLinearFace) {
    // The inner box's corners: along world axis i, Σ_j |frame_ij| h_j; then the rounding.
    half = frame_.cwiseAbs() * half_extent_mm_ + Eigen::Vector3d::Constant(edge_radius_mm_);
  } else {
    // The inner cylinder (radius a, half length l along the elevation axis u): along world axis
    // i, l |u_i| from its axis and a √(1 − u_i²) from its end discs; then the rounding.
    const Eigen::Vector3d u = frame_.col(1);
    const double a = half_extent_mm_.x(), l = half_extent_mm_.y();
    for (int i = 0; i < 3; ++i) {
      half[i] =
          l * std::abs(u[i]) + a * std::sqrt(std::max(0.0, 1.0 - u[i] * u[i])) + edge_radius_mm_;
    }
  }
  return {center_mm_ - half, center_mm_ + half};
}

}  // namespace ultrasim::sim
