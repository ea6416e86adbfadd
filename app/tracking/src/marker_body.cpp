#include "ultrasim/tracking/marker_body.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace ultrasim::tracking {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The angle a face turns about its fold, away from the flat page: π minus the dihedral angle
// arccos(−1/√5).
const double kFoldAngle = std::acos(1.0 / std::sqrt(5.0));

Eigen::Vector3d on_page(const Eigen::Vector2d& p) {
  return {p.x(), p.y(), 0.0};
}

// The detected square of a marker centred at `centre` (page mm) with its top toward `up`, in
// detector order (bottom-left, bottom-right, top-right, top-left as printed).
std::array<Eigen::Vector2d, 4> printed_corners(const Eigen::Vector2d& centre,
                                               const Eigen::Vector2d& up, double half_side) {
  const Eigen::Vector2d right(-up.y(), up.x());  // page y points down
  return {centre - half_side * (up + right), centre - half_side * (up - right),
          centre + half_side * (up + right), centre + half_side * (up - right)};
}

void check_sides(const char* what, double edge_mm, double printed_side_mm) {
  if (!(edge_mm > 0.0) || !std::isfinite(edge_mm) || !(printed_side_mm > 0.0) ||
      !(printed_side_mm < edge_mm * 2.0)) {
    throw std::invalid_argument(std::string(what) + ": edge " + std::to_string(edge_mm) +
                                " mm and marker side " + std::to_string(printed_side_mm) +
                                " mm must be positive and the marker must fit the face");
  }
}

// The cube's faces as (outward normal, the printed marker's up); right = up × normal keeps the
// marker unmirrored seen from outside.
const std::array<std::pair<Eigen::Vector3d, Eigen::Vector3d>, 6> kCubeFaces = {{
    {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()},
    {-Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()},
    {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ()},
    {-Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ()},
    {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()},
    {-Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()},
}};

}  // namespace

double largest_marker_side_mm(double edge_mm) {
  // The pentagon's edges are inradius r from its centre, their normals at 72° steps from "up".
  // A centred square of half-side h reaches h·(|sin θ| + |cos θ|) along a normal at θ; the worst
  // normals, at ±144°, allow h = r / (sin 144° + |cos 144°|).
  const double reach = std::sin(0.8 * kPi) + std::abs(std::cos(0.8 * kPi));
  return 2.0 * 0.98 * pentagon_inradius_mm(edge_mm) / reach;
}

std::vector<Eigen::Isometry3d> fold_dodecahedron_net(const DodecahedronNet& net) {
  const std::size_t n = net.faces.size();
  std::vector<Eigen::Isometry3d> placed(n, Eigen::Isometry3d::Identity());
  std::vector<bool> done(n, false);
  done[0] = true;
  // Face 0 stays on the page; the page's z points away from the reader, so the solid grows
  // toward +z and the print faces out. Each fold turns the child about the shared edge.
  for (bool grew = true; grew;) {
    grew = false;
    for (const auto& fold : net.folds) {
      for (int side = 0; side < 2; ++side) {
        const auto parent = static_cast<std::size_t>(fold[side]);
        const auto child = static_cast<std::size_t>(fold[1 - side]);
        if (!done[parent] || done[child]) continue;
        // The shared edge: two corners of the child that the parent also has.
        std::vector<Eigen::Vector2d> shared;
        for (const auto& c : net.faces[child].corners_mm) {
          for (const auto& p : net.faces[parent].corners_mm) {
            if ((c - p).norm() < 1e-6 * net.edge_mm) shared.push_back(c);
          }
        }
        if (shared.size() != 2) {
          throw std::invalid_argument("fold_dodecahedron_net: faces " + std::to_string(parent) +
                                      " and " + std::to_string(child) + " share no edge");
        }
        const Eigen::Vector3d a = on_page(shared[0]), b = on_page(shared[1]);
        const Eigen::Vector3d axis = (b - a).normalized();
        const Eigen::Vector3d centre = on_page(net.faces[child].centre_mm);
        Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
        for (double sign : {1.0, -1.0}) {
          turn = Eigen::Translation3d(a) * Eigen::AngleAxisd(sign * kFoldAngle, axis) *
                 Eigen::Translation3d(-a);
          if ((turn * centre).z() > 0.0) break;
        }
        placed[child] = placed[parent] * turn;
        done[child] = true;
        grew = true;
      }
    }
  }
  for (std::size_t f = 0; f < n; ++f) {
    if (!done[f]) {
      throw std::invalid_argument("fold_dodecahedron_net: face " + std::to_string(f) +
                                  " is not connected by folds");
    }
  }
  // Centre the solid on its faces' centres.
  Eigen::Vector3d middle = Eigen::Vector3d::Zero();
  for (std::size_t f = 0; f < n; ++f) middle += placed[f] * on_page(net.faces[f].centre_mm);
  middle /= static_cast<double>(n);
  for (auto& p : placed) p = Eigen::Translation3d(-middle) * p;
  return placed;
}

hal::MarkerBody dodecahedron_marker_body(double edge_mm, double printed_side_mm) {
  check_sides("dodecahedron_marker_body", edge_mm, printed_side_mm);
  const DodecahedronNet net = make_dodecahedron_net(edge_mm);
  const auto placed = fold_dodecahedron_net(net);
  const double half_side = 0.5 * kTag36h11BorderFraction * printed_side_mm;
  hal::MarkerBody body{"dodecahedron", "tag36h11", {}};
  for (std::size_t f = 0; f < net.faces.size(); ++f) {
    const NetFace& face = net.faces[f];
    hal::BodyMarker marker;
    marker.id = static_cast<int>(f);
    const auto corners = printed_corners(face.centre_mm, face.up, half_side);
    for (int k = 0; k < 4; ++k) marker.corners_mm[k] = placed[f] * on_page(corners[k]);
    // Out of the body: the page's −z, where the reader is.
    marker.outward_normal = placed[f].linear() * -Eigen::Vector3d::UnitZ();
    body.markers.push_back(marker);
  }
  return body;
}

hal::MarkerBody cube_marker_body(double edge_mm, double printed_side_mm) {
  check_sides("cube_marker_body", edge_mm, printed_side_mm);
  const double half_side = 0.5 * kTag36h11BorderFraction * printed_side_mm;
  hal::MarkerBody body{"cube", "tag36h11", {}};
  for (int f = 0; f < 6; ++f) {
    const auto& [normal, up] = kCubeFaces[static_cast<std::size_t>(f)];
    const Eigen::Vector3d right = up.cross(normal);
    const Eigen::Vector3d centre = 0.5 * edge_mm * normal;
    hal::BodyMarker marker;
    marker.id = f;
    marker.corners_mm = {centre - half_side * (up + right), centre - half_side * (up - right),
                         centre + half_side * (up + right), centre + half_side * (up - right)};
    marker.outward_normal = normal;
    body.markers.push_back(marker);
  }
  return body;
}

Eigen::Isometry3d rigid_from_xyz_rotvec_deg(const std::array<double, 6>& v) {
  const Eigen::Vector3d rotation(v[3], v[4], v[5]);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  const double degrees = rotation.norm();
  if (degrees > 0.0) {
    out.linear() = Eigen::AngleAxisd(degrees * kPi / 180.0, rotation / degrees).toRotationMatrix();
  }
  out.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return out;
}

std::vector<std::vector<Eigen::Vector3d>> dodecahedron_faces(double edge_mm) {
  const DodecahedronNet net = make_dodecahedron_net(edge_mm);
  const auto placed = fold_dodecahedron_net(net);
  std::vector<std::vector<Eigen::Vector3d>> faces;
  for (std::size_t f = 0; f < net.faces.size(); ++f) {
    std::vector<Eigen::Vector3d> polygon;
    for (const auto& c : net.faces[f].corners_mm) polygon.push_back(placed[f] * on_page(c));
    // The net's corners run clockwise seen from the reader, who is outside.
    std::reverse(polygon.begin(), polygon.end());
    faces.push_back(polygon);
  }
  return faces;
}

std::vector<std::vector<Eigen::Vector3d>> cube_faces(double edge_mm) {
  std::vector<std::vector<Eigen::Vector3d>> faces;
  const double h = 0.5 * edge_mm;
  for (const auto& [normal, up] : kCubeFaces) {
    const Eigen::Vector3d right = up.cross(normal);
    const Eigen::Vector3d centre = h * normal;
    faces.push_back({centre - h * (up + right), centre - h * (up - right),
                     centre + h * (up + right), centre + h * (up - right)});
  }
  return faces;
}

}  // namespace ultrasim::tracking
