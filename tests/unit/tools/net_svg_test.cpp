// The printable net's SVG: every face outlined, folds dashed, one marker per face that fits it.

#include "ultrasim/tools/net_svg.hpp"

#include <gtest/gtest.h>

#include <string>

namespace ultrasim::tools {
namespace {

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(NetSvg, OutlinesEveryFaceDashesTheFoldsAndCentresTheMarkers) {
  const tracking::DodecahedronNet net = tracking::make_dodecahedron_net(40.0, 10.0);
  // A 2 × 2 checker on every face.
  const FaceMarker checker{2, {true, false, false, true}, 30.0, "m"};
  const std::vector<FaceMarker> markers(12, checker);
  const std::string svg = dodecahedron_net_svg(net, markers);
  EXPECT_NE(svg.find("width=\"" + std::to_string(net.size_mm.x()).substr(0, 5)), std::string::npos);
  EXPECT_EQ(count(svg, "<line "), 60);            // 12 faces × 5 edges
  EXPECT_EQ(count(svg, "stroke-dasharray"), 22);  // 11 folds, drawn by both their faces
  EXPECT_EQ(count(svg, "<g transform=\"translate("), 12);
  EXPECT_EQ(count(svg, "fill=\"black\""), 24);  // two black cells a face
  EXPECT_EQ(count(svg, "</svg>"), 1);

  const FaceMarker too_big{2, {true, false, false, true}, 60.0, "big"};
  EXPECT_THROW(dodecahedron_net_svg(net, std::vector<FaceMarker>{too_big}), std::invalid_argument);
  const FaceMarker wrong_cells{3, {true}, 10.0, "bad"};
  EXPECT_THROW(dodecahedron_net_svg(net, std::vector<FaceMarker>{wrong_cells}),
               std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::tools
