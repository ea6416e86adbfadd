#include "ultrasim/tracking/dodecahedron_net.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

namespace ultrasim::tracking {

namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector2d reflect(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                        const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = (b - a).normalized();
  const Eigen::Vector2d foot = a + (p - a).dot(d) * d;
  return 2.0 * foot - p;
}

// The face across edge (k, k+1) of `face`: its mirror image in that edge's line.
NetFace across(const NetFace& face, int k) {
  const Eigen::Vector2d& a = face.corners_mm[k];
  const Eigen::Vector2d& b = face.corners_mm[(k + 1) % 5];
  NetFace out;
  // Reflection reverses the order; keep corners going the same way round, starting on the fold.
  for (int i = 0; i < 5; ++i)
    out.corners_mm[i] = reflect(face.corners_mm[(k + 1 - i + 5) % 5], a, b);
  out.centre_mm = reflect(face.centre_mm, a, b);
  return out;
}

void set_up(NetFace& face) {
  face.up = ((face.corners_mm[0] + face.corners_mm[1]) / 2 - face.centre_mm).normalized();
}

}  // namespace

double pentagon_inradius_mm(double edge_mm) {
  return edge_mm / (2.0 * std::tan(kPi / 5));
}

DodecahedronNet make_dodecahedron_net(double edge_mm, double margin_mm) {
  if (!(edge_mm > 0.0) || !std::isfinite(edge_mm)) {
    throw std::invalid_argument("make_dodecahedron_net: the edge length must be > 0 mm");
  }
  DodecahedronNet net;
  net.edge_mm = edge_mm;
  const double circumradius = edge_mm / (2.0 * std::sin(kPi / 5));
  NetFace centre;
  centre.centre_mm = Eigen::Vector2d::Zero();
  for (int i = 0; i < 5; ++i) {
    const double angle = -kPi / 2 + 2 * kPi * i / 5;
    centre.corners_mm[i] = circumradius * Eigen::Vector2d(std::cos(angle), std::sin(angle));
  }
  // The first flower: the centre (face 0) and a petal across each of its edges (faces 1–5).
  net.faces.push_back(centre);
  for (int k = 0; k < 5; ++k) {
    net.faces.push_back(across(centre, k));
    net.folds.push_back({0, k + 1});
  }
  // The second: the first turned 180° about the middle of petal 1's edge farthest from the
  // centre (its corners 2–3, counting from the fold at 0–1), so petal 1 and its image meet there.
  const NetFace& petal = net.faces[1];
  const Eigen::Vector2d pivot = (petal.corners_mm[2] + petal.corners_mm[3]) / 2;
  for (int f = 0; f < 6; ++f) {
    NetFace turned = net.faces[f];
    for (auto& c : turned.corners_mm) c = 2 * pivot - c;
    turned.centre_mm = 2 * pivot - turned.centre_mm;
    net.faces.push_back(turned);
  }
  for (int k = 0; k < 5; ++k) net.folds.push_back({6, 7 + k});
  net.folds.push_back({1, 7});
  // Onto the page: the bounding box from (margin, margin).
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = Eigen::Vector2d::Constant(-1e300);
  for (const auto& f : net.faces) {
    for (const auto& c : f.corners_mm) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
  }
  const Eigen::Vector2d shift = Eigen::Vector2d::Constant(margin_mm) - lo;
  for (auto& f : net.faces) {
    for (auto& c : f.corners_mm) c += shift;
    f.centre_mm += shift;
    set_up(f);
  }
  net.size_mm = hi - lo + Eigen::Vector2d::Constant(2 * margin_mm);
  return net;
}

}  // namespace ultrasim::tracking
