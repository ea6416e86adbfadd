// The test surfaces themselves: the renderer's surface tests and the screenshot rely on them
// being closed and wound counter-clockwise outside, as FrameInput::surfaces promises.
#include "synthetic_surfaces.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

#include "synthetic_scene.hpp"

namespace ultrasim::render::testing {
namespace {

// Closed and consistently wound: every directed edge once, and its reverse once, so every edge
// is shared by exactly two triangles that agree on the orientation. Vertices are compared by
// position because boxes and caps duplicate them for their normals.
void expect_closed_and_outward(const SyntheticSurface& s) {
  using Point = std::array<float, 3>;
  std::map<std::pair<Point, Point>, int> directed;
  for (std::size_t t = 0; t < s.triangle_count(); ++t) {
    for (int e = 0; e < 3; ++e) {
      const Point a = s.vertex(s.triangles[3 * t + e]);
      const Point b = s.vertex(s.triangles[3 * t + (e + 1) % 3]);
      ++directed[{a, b}];
    }
  }
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1);
    const auto reverse = directed.find({edge.second, edge.first});
    ASSERT_NE(reverse, directed.end());
    EXPECT_EQ(reverse->second, 1);
  }
  EXPECT_GT(s.signed_volume_x6(), 0.0);
  ASSERT_EQ(s.normals.size(), s.positions_mm.size());
  for (std::size_t v = 0; v < s.vertex_count(); ++v) {
    const float* n = &s.normals[3 * v];
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0f, 1e-4f);
  }
}

TEST(SyntheticSurfaces, BoxIsClosedAndWoundOutwardWithItsVolume) {
  const SyntheticSurface box = make_box({1, 2, 3}, {4, 6, 8});
  EXPECT_EQ(box.triangle_count(), 12u);
  expect_closed_and_outward(box);
  EXPECT_NEAR(box.signed_volume_x6() / 6.0, 3.0 * 4.0 * 5.0, 1e-3);
}

TEST(SyntheticSurfaces, TubeIsClosedAndWoundOutwardWithTheCountPromised) {
  TubeShape shape;
  shape.y0_mm = 0.0f;
  shape.y1_mm = 30.0f;
  shape.centre_x_mm = [](float) { return 10.0f; };
  shape.centre_z_mm = [](float y) { return 20.0f + 0.1f * y; };
  shape.half_x_mm = [](float) { return 5.0f; };
  shape.half_z_mm = [](float y) { return 5.0f - 0.1f * y; };
  const SyntheticSurface tube = make_tube(shape, 24, 10);
  EXPECT_EQ(tube.triangle_count(), 2u * 24 * 10 + 2 * 24);
  expect_closed_and_outward(tube);
}

TEST(SyntheticSurfaces, SceneStructuresHaveAboutTheTrianglesAskedFor) {
  for (const int wanted : {15000, 60000}) {
    SyntheticScene scene = make_synthetic_scene(16, 16);
    add_synthetic_structures(scene, wanted);
    ASSERT_EQ(scene.frame.surfaces.size(), 4u);
    std::size_t triangles = 0;
    for (const SurfaceView& v : scene.frame.surfaces) triangles += v.triangles.size() / 3;
    EXPECT_NEAR(static_cast<double>(triangles), wanted, 0.05 * wanted);
    for (const SyntheticSurface& s : scene.structures) expect_closed_and_outward(s);
  }
}

}  // namespace
}  // namespace ultrasim::render::testing
