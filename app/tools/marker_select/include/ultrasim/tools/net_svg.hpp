#pragma once

#include <span>
#include <string>
#include <vector>

#include "ultrasim/tracking/dodecahedron_net.hpp"

namespace ultrasim::tools {

// What goes on one face: a square grid of cells (row-major, true = black) drawn centred on the
// face, turned with the face's "up", `side_mm` across; and a label printed below it.
struct FaceMarker {
  int cells_per_side = 0;
  std::vector<bool> black;
  double side_mm = 0.0;
  std::string label;
};

// The net as an SVG page in millimetres: cut lines solid, folds dashed, one marker per face (in
// face order; fewer markers leave faces blank). Throws std::invalid_argument for a marker whose
// cell count does not match its grid or that does not fit inside its face.
std::string dodecahedron_net_svg(const tracking::DodecahedronNet& net,
                                 std::span<const FaceMarker> markers);

}  // namespace ultrasim::tools
