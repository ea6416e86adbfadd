#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace ultrasim::tracking {

// A flat net of the regular dodecahedron, to print, cut out and fold: twelve regular pentagons
// with the given edge length, in mm on the page (y down, as SVG draws). The classic net: a
// "flower" (a face and its five neighbours) and the same flower turned 180° about the midpoint
// of an outer edge of one of its petals, so the two flowers meet along that edge.
struct NetFace {
  std::array<Eigen::Vector2d, 5> corners_mm;  // in order around the face
  Eigen::Vector2d centre_mm;
  // Direction from the centre to the middle of corners 0–1: the face's "up" on the page.
  Eigen::Vector2d up;
};

struct DodecahedronNet {
  double edge_mm = 0.0;
  std::vector<NetFace> faces;  // 12
  // Pairs of faces sharing an edge in the net (the folds): 11 for a net of 12 faces.
  std::vector<std::array<int, 2>> folds;
  Eigen::Vector2d size_mm = Eigen::Vector2d::Zero();  // the bounding box; corners ≥ 0
};

// The net for an edge length in mm (> 0; throws std::invalid_argument otherwise), moved so its
// bounding box starts at (margin_mm, margin_mm).
DodecahedronNet make_dodecahedron_net(double edge_mm, double margin_mm = 0.0);

// The inradius of a regular pentagon of edge `edge_mm`: the largest circle a marker fits in.
double pentagon_inradius_mm(double edge_mm);

}  // namespace ultrasim::tracking
