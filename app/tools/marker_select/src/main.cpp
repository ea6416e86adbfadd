// ultrasim-marker-select: the published marker selection for the camera dodecahedron, run in
// full (C(60, 6) sets of 3×3 patterns), and the worst case of the AprilTag families we use, for
// comparison.

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>

#include "ultrasim/tools/code_distance.hpp"
#include "ultrasim/tools/net_svg.hpp"
#include "ultrasim/tracking/dodecahedron_net.hpp"
#include "ultrasim/tracking/marker_body.hpp"
#include "ultrasim/tracking/marker_selection.hpp"

namespace {

using namespace ultrasim;

int family_distance(apriltag_family_t* family) {
  const tools::CodeFamily f{{family->codes, family->ncodes},
                            {family->bit_x, family->nbits},
                            {family->bit_y, family->nbits}};
  return tools::min_distance_under_rotation(f);
}

// The twelve selected 3×3 patterns, each inside a black frame one patch wide (5 × 5 cells).
std::vector<tools::FaceMarker> pattern_markers(const tracking::MarkerSet& best, double side_mm) {
  const auto patterns = tracking::unique_patterns();
  std::vector<tools::FaceMarker> markers;
  for (int i : best.indices) {
    tools::FaceMarker m{5, std::vector<bool>(25, true), side_mm, "3x3 #" + std::to_string(i)};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        m.black[static_cast<std::size_t>((r + 1) * 5 + c + 1)] =
            ((patterns[static_cast<std::size_t>(i)] >> (r * 3 + c)) & 1) != 0;
      }
    }
    markers.push_back(std::move(m));
  }
  return markers;
}

// tag36h11 ids 0–11 as AprilTag draws them (its white outer ring included).
std::vector<tools::FaceMarker> tag_markers(double side_mm) {
  apriltag_family_t* family = tag36h11_create();
  std::vector<tools::FaceMarker> markers;
  for (int id = 0; id < 12; ++id) {
    image_u8_t* image = apriltag_to_image(family, static_cast<uint32_t>(id));
    tools::FaceMarker m{image->width, {}, side_mm, "tag36h11 id " + std::to_string(id)};
    for (int y = 0; y < image->height; ++y) {
      for (int x = 0; x < image->width; ++x)
        m.black.push_back(image->buf[y * image->stride + x] == 0);
    }
    image_u8_destroy(image);
    markers.push_back(std::move(m));
  }
  tag36h11_destroy(family);
  return markers;
}

int run_search(const std::string& net_path, double edge_mm, const std::string& kind) {
  const auto start = std::chrono::steady_clock::now();
  const tracking::MarkerSet best = tracking::select_markers();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto patterns = tracking::unique_patterns();
  std::printf("searched %lld sets of six positives (with their negatives) in %.2f s\n",
              static_cast<long long>(best.combinations_searched), seconds);
  std::printf("best: smallest similarity %d patches, sum %d (published: 2 and 568)\n",
              best.min_similarity, best.sum_similarity);
  std::printf("indices (0-59 positives, +60 their negatives):");
  for (int i : best.indices) std::printf(" %d", i);
  std::printf("\npatterns (# black, . white), one per dodecahedron face:\n");
  for (int row = 0; row < 3; ++row) {
    for (int i : best.indices) {
      for (int col = 0; col < 3; ++col) {
        std::putchar(((patterns[static_cast<std::size_t>(i)] >> (row * 3 + col)) & 1) != 0 ? '#'
                                                                                           : '.');
      }
      std::putchar(' ');
    }
    std::putchar('\n');
  }
  apriltag_family_t* t36 = tag36h11_create();
  apriltag_family_t* t41 = tagStandard41h12_create();
  std::printf(
      "worst case (fewest differing bits, any rotation): 3x3 markers %d of 9 bits; "
      "tag36h11 %d of 36 (%u codes); tagStandard41h12 %d of 41 (%u codes)\n",
      best.min_similarity, family_distance(t36), t36->ncodes, family_distance(t41), t41->ncodes);
  tag36h11_destroy(t36);
  tagStandard41h12_destroy(t41);
  if (net_path.empty()) return 0;
  const tracking::DodecahedronNet net = tracking::make_dodecahedron_net(edge_mm, 10.0);
  // As large as the face allows: the size the camera tracker's model of the dodecahedron
  // (tracking::dodecahedron_marker_body) assumes. The 3×3 patterns have no white ring of their
  // own: they are printed at the AprilTag's black border size, leaving the card as their ring.
  const double side_mm = tracking::largest_marker_side_mm(edge_mm);
  const auto markers = kind == "tag36h11"
                           ? tag_markers(side_mm)
                           : pattern_markers(best, tracking::kTag36h11BorderFraction * side_mm);
  std::ofstream out(net_path);
  if (!out) throw std::runtime_error(net_path + ": cannot write");
  out << tools::dodecahedron_net_svg(net, markers);
  std::printf("net: %s, %.0f x %.0f mm, edge %.1f mm, markers %.1f mm (%s)\n", net_path.c_str(),
              net.size_mm.x(), net.size_mm.y(), edge_mm, side_mm, kind.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "ultrasim marker selection: the published 3x3 markers for the camera dodecahedron, their "
      "worst case beside AprilTag's, and a printable net"};
  std::string net_path, kind = "3x3";
  double edge_mm = 40.0;
  app.add_option("--net", net_path, "write a printable dodecahedron net (SVG, mm) to this file");
  app.add_option("--edge-mm", edge_mm, "the net's edge length, mm")
      ->check(CLI::Range(5.0, 500.0))
      ->capture_default_str();
  app.add_option("--markers", kind, "markers on the net's faces: 3x3 (selected) or tag36h11")
      ->check(CLI::IsMember({"3x3", "tag36h11"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    return run_search(net_path, edge_mm, kind);
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-marker-select: " << e.what() << '\n';
    return 1;
  }
}
