// Closed surfaces (vessels, nerve, bone) in the 3D view: drawn lit, in their own hue, inside the
// mesh; culled, blended and skipped as SceneRenderer promises; the rest of the screen untouched.
// Where a surface lands is found by difference with the same frame drawn without it, so these
// tests do not depend on the camera's framing.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "allocation_counter.hpp"
#include "synthetic_scene.hpp"
#include "synthetic_surfaces.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/scene_renderer.hpp"

namespace ultrasim::render {
namespace {

using testing::SyntheticScene;
using testing::SyntheticSurface;

constexpr int kWidthPx = 960;
constexpr int kHeightPx = 540;

// A box in the front-left part of the synthetic tissue: in front of the image plane (y = 20 mm)
// and clear of the probe, so nothing but mesh lines lies between it and the camera.
constexpr std::array<float, 3> kBoxLoMm{8.0f, 26.0f, 14.0f};
constexpr std::array<float, 3> kBoxHiMm{28.0f, 38.0f, 34.0f};

class SurfaceRendering : public ::testing::Test {
 protected:
  SurfaceRendering()
      : display_(offscreen_display_settings(kWidthPx, kHeightPx)),
        renderer_(std::make_unique<SceneRenderer>(display_)),
        scene_(testing::make_synthetic_scene()) {}

  // Draws the synthetic scene with these surfaces and reads the screen back.
  RgbaImage draw(std::span<const SurfaceView> surfaces, SceneRenderer* renderer = nullptr) {
    FrameInput frame = scene_.frame;
    frame.surfaces = surfaces;
    display_.begin_frame();
    (renderer != nullptr ? *renderer : *renderer_).draw(frame);
    display_.end_frame();
    return display_.read_pixels();
  }
  RgbaImage draw_one(const SurfaceView& surface) { return draw(std::span(&surface, 1)); }
  // The same, from a renderer that has never drawn anything else.
  RgbaImage draw_fresh(std::span<const SurfaceView> surfaces) {
    SceneRenderer fresh(display_);
    return draw(surfaces, &fresh);
  }

  OffscreenDisplay display_;
  std::unique_ptr<SceneRenderer> renderer_;
  SyntheticScene scene_;
};

struct Pixel {
  int x, y;
  std::uint8_t r, g, b;
};

// Pixels that differ between two images of the same size.
std::vector<Pixel> changed_pixels(const RgbaImage& base, const RgbaImage& with) {
  std::vector<Pixel> out;
  for (int y = 0; y < base.height; ++y) {
    for (int x = 0; x < base.width; ++x) {
      const std::uint8_t* a = base.at(x, y);
      const std::uint8_t* b = with.at(x, y);
      if (a[0] != b[0] || a[1] != b[1] || a[2] != b[2]) out.push_back({x, y, b[0], b[1], b[2]});
    }
  }
  return out;
}

bool same_region(const RgbaImage& a, const RgbaImage& b, const PixelRect& r) {
  for (int y = r.y_px; y < r.y_px + r.height_px; ++y) {
    for (int x = r.x_px; x < r.x_px + r.width_px; ++x) {
      if (!std::equal(a.at(x, y), a.at(x, y) + 4, b.at(x, y))) return false;
    }
  }
  return true;
}

// The pixel is the colour scaled by one light factor (Lambert + ambient keeps the hue): its
// channels relative to the largest one match the colour's within tolerance.
bool has_hue_of(const Pixel& p, const std::array<float, 4>& rgba, float tolerance = 0.06f) {
  const float c[3] = {static_cast<float>(p.r), static_cast<float>(p.g), static_cast<float>(p.b)};
  const int k = static_cast<int>(std::max_element(rgba.begin(), rgba.begin() + 3) - rgba.begin());
  if (c[k] < 30.0f) return false;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(c[i] / c[k] - rgba[i] / rgba[k]) > tolerance) return false;
  }
  return true;
}

TEST_F(SurfaceRendering, OpaqueSurfaceDrawsLitPixelsInItsHueInsideThe3dView) {
  const SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  const RgbaImage without = draw({});
  const RgbaImage with = draw_one(box.view(testing::kArteryRgba));
  const ScreenLayout& layout = renderer_->layout();

  const std::vector<Pixel> changed = changed_pixels(without, with);
  ASSERT_GT(changed.size(), 1000u);
  for (const Pixel& p : changed)
    ASSERT_TRUE(layout.view_3d.contains(p.x, p.y)) << p.x << "," << p.y;
  EXPECT_TRUE(same_region(without, with, layout.bscan_panel));
  EXPECT_TRUE(same_region(without, with, layout.header));

  // Nearly all of it is the surface itself (the rest: mesh lines in front of it, edges).
  std::vector<int> red;
  for (const Pixel& p : changed) {
    if (has_hue_of(p, testing::kArteryRgba)) red.push_back(p.r);
  }
  EXPECT_GT(red.size(), changed.size() * 85 / 100);
  // Lit: three faces at different angles to the headlight give different brightness, none
  // darker than the ambient share and the one facing the eye most nearly full colour.
  const auto [darkest, brightest] = std::minmax_element(red.begin(), red.end());
  const float full_r = testing::kArteryRgba[0] * 255.0f;
  EXPECT_GE(*darkest, static_cast<int>(0.25f * full_r));
  EXPECT_GE(*brightest, static_cast<int>(0.7f * full_r));
  EXPECT_GE(*brightest - *darkest, 30);
}

TEST_F(SurfaceRendering, EveryKioskColourKeepsItsHue) {
  const SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  const RgbaImage without = draw({});
  for (const auto& rgba :
       {testing::kVeinRgba, testing::kArteryRgba, testing::kNerveRgba, testing::kBoneRgba}) {
    const std::vector<Pixel> changed = changed_pixels(without, draw_one(box.view(rgba)));
    ASSERT_GT(changed.size(), 1000u);
    const auto matching = std::count_if(changed.begin(), changed.end(),
                                        [&](const Pixel& p) { return has_hue_of(p, rgba); });
    EXPECT_GT(matching, static_cast<long>(changed.size() * 85 / 100))
        << rgba[0] << " " << rgba[1] << " " << rgba[2];
  }
}

TEST_F(SurfaceRendering, FlatShadingWithoutNormalsMatchesFaceNormals) {
  // The box's normals are its face normals, so shading from derivatives must give the same
  // picture: same faces lit, same orientation of the derivative normal.
  const SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  const RgbaImage smooth = draw_one(box.view(testing::kVeinRgba, true));
  const RgbaImage flat = draw_one(box.view(testing::kVeinRgba, false));
  const std::vector<Pixel> drawn = changed_pixels(draw({}), smooth);
  ASSERT_GT(drawn.size(), 1000u);
  std::size_t close = 0;
  for (const Pixel& p : drawn) {
    const std::uint8_t* f = flat.at(p.x, p.y);
    if (std::abs(f[0] - p.r) <= 3 && std::abs(f[1] - p.g) <= 3 && std::abs(f[2] - p.b) <= 3) {
      ++close;
    }
  }
  EXPECT_GT(close, drawn.size() * 97 / 100);
}

TEST_F(SurfaceRendering, BackFacesOfOpaqueSurfacesAreCulled) {
  // A horizontal square facing up (-z, towards the skin and the camera above it), then the same
  // square wound the other way: its back to the camera.
  SyntheticSurface up;
  const float z = 12.0f;
  up.add_vertex({kBoxLoMm[0], kBoxLoMm[1], z});
  up.add_vertex({kBoxLoMm[0], kBoxHiMm[1], z});
  up.add_vertex({kBoxHiMm[0], kBoxLoMm[1], z});
  up.add_vertex({kBoxHiMm[0], kBoxHiMm[1], z});
  up.triangles = {0, 1, 2, 2, 1, 3};
  SyntheticSurface down = up;
  down.triangles = {0, 2, 1, 2, 3, 1};

  const RgbaImage without = draw({});
  EXPECT_GT(changed_pixels(without, draw_one(up.view(testing::kBoneRgba, false))).size(), 500u);
  EXPECT_TRUE(changed_pixels(without, draw_one(down.view(testing::kBoneRgba, false))).empty());
}

TEST_F(SurfaceRendering, TranslucentSurfaceBlendsAndShowsWhatIsInside) {
  // A red opaque box inside a larger translucent blue one: the red shows through.
  const SyntheticSurface inner = testing::make_box({14, 29, 20}, {22, 35, 28});
  const SyntheticSurface outer = testing::make_box(kBoxLoMm, kBoxHiMm);
  std::array<float, 4> glass = testing::kVeinRgba;
  glass[3] = 0.4f;
  const std::array<SurfaceView, 2> both = {inner.view(testing::kArteryRgba), outer.view(glass)};
  // Listed the other way round too: the opaque pass goes first whatever the order.
  const std::array<SurfaceView, 2> swapped = {both[1], both[0]};

  const RgbaImage without = draw({});
  const RgbaImage opaque_outer = draw_one(outer.view(testing::kVeinRgba));
  const RgbaImage glass_only = draw_one(outer.view(glass));
  const RgbaImage inside = draw(both);
  EXPECT_EQ(changed_pixels(inside, draw(swapped)).size(), 0u);

  // Blended: between the background and the opaque surface, over the glass box's footprint.
  const std::vector<Pixel> footprint = changed_pixels(without, opaque_outer);
  ASSERT_GT(footprint.size(), 1000u);
  double glass_diff = 0.0;
  double opaque_diff = 0.0;
  for (const Pixel& p : footprint) {
    const std::uint8_t* g = glass_only.at(p.x, p.y);
    const std::uint8_t* o = opaque_outer.at(p.x, p.y);
    const std::uint8_t* w = without.at(p.x, p.y);
    for (int c = 0; c < 3; ++c) {
      glass_diff += std::abs(g[c] - w[c]);
      opaque_diff += std::abs(o[c] - w[c]);
    }
  }
  EXPECT_GT(glass_diff, 0.15 * opaque_diff);
  EXPECT_LT(glass_diff, 0.85 * opaque_diff);

  // Where the inner box lies, the picture is red-dominated through the blue glass.
  const std::vector<Pixel> inner_footprint =
      changed_pixels(without, draw_one(inner.view(testing::kArteryRgba)));
  ASSERT_GT(inner_footprint.size(), 200u);
  std::size_t reddish = 0;
  for (const Pixel& p : inner_footprint) {
    const std::uint8_t* q = inside.at(p.x, p.y);
    const std::uint8_t* g = glass_only.at(p.x, p.y);
    if (q[0] > q[2] && q[0] > g[0] + 30) ++reddish;
  }
  EXPECT_GT(reddish, inner_footprint.size() * 80 / 100);
}

TEST_F(SurfaceRendering, EmptySurfacesDrawTheScreenAsBefore) {
  const RgbaImage before = draw({});
  const SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  std::array<float, 4> glass = testing::kNerveRgba;
  glass[3] = 0.5f;
  const std::array<SurfaceView, 2> two = {box.view(testing::kArteryRgba, false),
                                          box.view(glass, true)};
  (void)draw(two);
  // No GL state left behind (culling, depth writes, the normal attribute): identical again, and
  // identical to a renderer that never saw a surface.
  EXPECT_TRUE(changed_pixels(before, draw({})).empty());
  EXPECT_TRUE(changed_pixels(before, draw_fresh({})).empty());
}

TEST_F(SurfaceRendering, BadSurfacesAreSkippedWithoutCrashing) {
  const RgbaImage without = draw({});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();

  SyntheticSurface first_nan = testing::make_box(kBoxLoMm, kBoxHiMm);
  first_nan.positions_mm[1] = nan;
  EXPECT_TRUE(changed_pixels(without, draw_one(first_nan.view(testing::kVeinRgba))).empty());
  SyntheticSurface first_inf = testing::make_box(kBoxLoMm, kBoxHiMm);
  first_inf.positions_mm[0] = -inf;
  EXPECT_TRUE(changed_pixels(without, draw_one(first_inf.view(testing::kVeinRgba))).empty());

  SyntheticSurface past_end = testing::make_box(kBoxLoMm, kBoxHiMm);
  past_end.triangles[7] = static_cast<std::uint32_t>(past_end.vertex_count());
  EXPECT_TRUE(changed_pixels(without, draw_one(past_end.view(testing::kVeinRgba))).empty());

  const SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  std::array<float, 4> nan_colour = testing::kVeinRgba;
  nan_colour[1] = nan;
  EXPECT_TRUE(changed_pixels(without, draw_one(box.view(nan_colour))).empty());
  std::array<float, 4> invisible = testing::kVeinRgba;
  invisible[3] = 0.0f;
  EXPECT_TRUE(changed_pixels(without, draw_one(box.view(invisible))).empty());
  EXPECT_TRUE(changed_pixels(without, draw_one(SurfaceView{})).empty());

  // Non-finite values past the first vertex reach the GPU, which drops those triangles; the
  // rest of the surface and the screen are drawn.
  SyntheticSurface later_nan = testing::make_box(kBoxLoMm, kBoxHiMm);
  for (std::size_t i = 12; i < later_nan.positions_mm.size(); i += 7) {
    later_nan.positions_mm[i] = (i % 2 == 0) ? nan : inf;
  }
  std::fill(later_nan.normals.begin() + 30, later_nan.normals.end(), nan);
  const RgbaImage survived = draw_one(later_nan.view(testing::kVeinRgba));
  EXPECT_TRUE(same_region(without, survived, renderer_->layout().bscan_panel));

  // A triangle span that is not a whole number of triangles: the last part is ignored; normals
  // of the wrong length: flat shading.
  SurfaceView ragged = box.view(testing::kVeinRgba);
  ragged.triangles = ragged.triangles.first(ragged.triangles.size() - 1);
  ragged.normals = ragged.normals.first(ragged.normals.size() - 3);
  EXPECT_FALSE(changed_pixels(without, draw_one(ragged)).empty());

  // And the renderer is still sound afterwards.
  EXPECT_TRUE(changed_pixels(without, draw({})).empty());
}

TEST_F(SurfaceRendering, ChangedTopologyAndMovedVerticesAreUploaded) {
  SyntheticSurface box = testing::make_box(kBoxLoMm, kBoxHiMm);
  const SurfaceView whole = box.view(testing::kArteryRgba);
  (void)draw_one(whole);

  // The same index storage, fewer triangles (only the pointer's length changed).
  SurfaceView half = whole;
  half.triangles = whole.triangles.first(18);
  EXPECT_TRUE(changed_pixels(draw_fresh(std::span(&half, 1)), draw_one(half)).empty());

  // Other index storage of the same length, other triangles.
  std::vector<std::uint32_t> other(whole.triangles.begin() + 18, whole.triangles.end());
  other.insert(other.end(), whole.triangles.begin(), whole.triangles.begin() + 18);
  other.resize(18);
  SurfaceView other_half = whole;
  other_half.triangles = other;
  EXPECT_TRUE(changed_pixels(draw_fresh(std::span(&other_half, 1)), draw_one(other_half)).empty());

  // Same indices, vertices moved (every frame of a deforming vessel).
  (void)draw_one(whole);
  for (std::size_t i = 0; i < box.positions_mm.size(); i += 3) box.positions_mm[i] += 6.0f;
  EXPECT_TRUE(changed_pixels(draw_fresh(std::span(&whole, 1)), draw_one(whole)).empty());

  // More surfaces, then fewer, then more again: slots are reused.
  const SyntheticSurface small = testing::make_box({14, 29, 20}, {22, 35, 28});
  const std::array<SurfaceView, 2> two = {small.view(testing::kNerveRgba), whole};
  (void)draw(two);
  (void)draw(std::span(&two[0], 1));
  EXPECT_TRUE(changed_pixels(draw_fresh(two), draw(two)).empty());
}

TEST_F(SurfaceRendering, SceneStructuresShowInTheirColours) {
  testing::add_synthetic_structures(scene_, 6000);
  const RgbaImage without = draw({});
  const RgbaImage with = draw(scene_.frame.surfaces);
  const std::vector<Pixel> changed = changed_pixels(without, with);
  for (const auto& rgba :
       {testing::kVeinRgba, testing::kArteryRgba, testing::kNerveRgba, testing::kBoneRgba}) {
    const auto matching = std::count_if(changed.begin(), changed.end(),
                                        [&](const Pixel& p) { return has_hue_of(p, rgba, 0.04f); });
    EXPECT_GT(matching, 300) << rgba[0] << " " << rgba[1] << " " << rgba[2];
  }
}

TEST_F(SurfaceRendering, DeformingSurfacesDoNotAllocateAfterTheFirstFrames) {
  testing::add_synthetic_structures(scene_, 4000);
  FrameInput frame = scene_.frame;
  RgbaImage image;
  const auto frame_once = [&](int i) {
    // Every vertex moves every frame, as the simulation moves them.
    for (testing::SyntheticSurface& s : scene_.structures) {
      for (std::size_t k = 2; k < s.positions_mm.size(); k += 3) {
        s.positions_mm[k] += (i % 2 == 0) ? 0.05f : -0.05f;
      }
    }
    frame.frame_index = i;
    display_.begin_frame();
    renderer_->draw(frame);
    display_.end_frame();
    display_.read_pixels_into(image);
  };
  frame_once(0);
  frame_once(1);
  ::ultrasim::testing::start_counting_allocations();
  for (int i = 2; i < 7; ++i) frame_once(i);
  EXPECT_EQ(::ultrasim::testing::stop_counting_allocations(), 0);
}

}  // namespace
}  // namespace ultrasim::render
