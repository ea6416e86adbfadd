#include "ultrasim/tools/net_svg.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace ultrasim::tools {

namespace {

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f", v);
  return text;
}

std::string escaped(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

bool same_point(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a - b).norm() < 1e-6;
}

// Whether edge (p, q) of a face is a fold: another face has the same two corners.
bool is_fold(const tracking::DodecahedronNet& net, int face, const Eigen::Vector2d& p,
             const Eigen::Vector2d& q) {
  for (const auto& [a, b] : net.folds) {
    if (a != face && b != face) continue;
    const auto& other = net.faces[static_cast<std::size_t>(a == face ? b : a)];
    bool has_p = false, has_q = false;
    for (const auto& c : other.corners_mm) {
      has_p = has_p || same_point(c, p);
      has_q = has_q || same_point(c, q);
    }
    if (has_p && has_q) return true;
  }
  return false;
}

}  // namespace

std::string dodecahedron_net_svg(const tracking::DodecahedronNet& net,
                                 std::span<const FaceMarker> markers) {
  std::ostringstream svg;
  const double w = net.size_mm.x(), h = net.size_mm.y();
  svg << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << number(w) << "mm\" height=\""
      << number(h) << "mm\" viewBox=\"0 0 " << number(w) << ' ' << number(h) << "\">\n"
      << "<title>Dodecahedron net, edge " << number(net.edge_mm)
      << " mm: cut the solid lines, fold the dashed ones</title>\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  const double inradius = tracking::pentagon_inradius_mm(net.edge_mm);
  for (std::size_t f = 0; f < net.faces.size(); ++f) {
    const auto& face = net.faces[f];
    for (int k = 0; k < 5; ++k) {
      const auto& p = face.corners_mm[k];
      const auto& q = face.corners_mm[(k + 1) % 5];
      const bool fold = is_fold(net, static_cast<int>(f), p, q);
      svg << "<line x1=\"" << number(p.x()) << "\" y1=\"" << number(p.y()) << "\" x2=\""
          << number(q.x()) << "\" y2=\"" << number(q.y())
          << "\" stroke=\"#555\" stroke-width=\"0.2\""
          << (fold ? " stroke-dasharray=\"2 1.5\"" : "") << "/>\n";
    }
    if (f >= markers.size()) continue;
    const FaceMarker& m = markers[f];
    const int n = m.cells_per_side;
    if (n <= 0 || m.black.size() != static_cast<std::size_t>(n * n)) {
      throw std::invalid_argument("dodecahedron_net_svg: face " + std::to_string(f) +
                                  "'s marker has " + std::to_string(m.black.size()) +
                                  " cells for a " + std::to_string(n) + "-cell side");
    }
    // Turned with the face's up, the square's corners reach farthest along the normal of the
    // edges at ±144° from up (tracking::largest_marker_side_mm).
    const double reach = std::sin(0.8 * M_PI) + std::abs(std::cos(0.8 * M_PI));
    if (m.side_mm / 2 * reach > inradius * (1.0 + 1e-9)) {
      throw std::invalid_argument("dodecahedron_net_svg: a " + number(m.side_mm) +
                                  " mm marker does not fit a face of edge " + number(net.edge_mm) +
                                  " mm");
    }
    // The marker's up is the face's up: turn the grid so its top row faces corners 0–1.
    const double degrees = std::atan2(face.up.x(), -face.up.y()) * 180.0 / M_PI;
    const double cell = m.side_mm / n;
    svg << "<g transform=\"translate(" << number(face.centre_mm.x()) << ' '
        << number(face.centre_mm.y()) << ") rotate(" << number(degrees) << ")\">\n";
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        if (!m.black[static_cast<std::size_t>(r * n + c)]) continue;
        // Cells overlap by a hair so no white seams show between black ones when printed.
        svg << "<rect x=\"" << number(-m.side_mm / 2 + c * cell) << "\" y=\""
            << number(-m.side_mm / 2 + r * cell) << "\" width=\"" << number(cell + 0.01)
            << "\" height=\"" << number(cell + 0.01) << "\" fill=\"black\"/>\n";
      }
    }
    svg << "<text x=\"0\" y=\"" << number(m.side_mm / 2 + 0.12 * inradius + 2.0)
        << "\" font-family=\"sans-serif\" font-size=\"3\" text-anchor=\"middle\" fill=\"#555\">"
        << escaped(m.label) << "</text>\n</g>\n";
  }
  svg << "</svg>\n";
  return svg.str();
}

}  // namespace ultrasim::tools
