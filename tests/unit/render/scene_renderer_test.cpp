#include "ultrasim/render/scene_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "allocation_counter.hpp"
#include "synthetic_scene.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"

namespace ultrasim::render {
namespace {

constexpr int kBscanW = 64;
constexpr int kBscanH = 48;

// A grey ramp in both directions, so a flipped or transposed image would not match:
// g = 3 * column + row.
std::vector<std::uint8_t> gradient_bscan() {
  std::vector<std::uint8_t> pixels(kBscanW * kBscanH);
  for (int y = 0; y < kBscanH; ++y) {
    for (int x = 0; x < kBscanW; ++x)
      pixels[y * kBscanW + x] = static_cast<std::uint8_t>(3 * x + y);
  }
  return pixels;
}

bool is_grey(const std::uint8_t* p) {
  return p[0] == p[1] && p[1] == p[2] && p[0] > 12;
}
bool is_red(const std::uint8_t* p) {
  return p[0] > 150 && p[1] < 100 && p[2] < 100;
}
bool is_amber(const std::uint8_t* p) {
  return p[0] > 200 && p[1] > 140 && p[1] < 200 && p[2] < 80;
}
// The ramp's ends, as drawn near the camera (far lines fade towards the panel colour).
bool is_mesh_blue(const std::uint8_t* p) {
  return p[2] > 100 && p[2] > 2 * p[0] && p[2] > p[1] + 40;
}
bool is_mesh_red(const std::uint8_t* p) {
  return p[0] > 100 && p[0] > 2 * p[1] && p[0] > 2 * p[2];
}

// The 3D view without its colour-bar legend (whose blue and red would count as mesh).
PixelRect scene_region(const ScreenLayout& layout) {
  PixelRect r = layout.view_3d;
  r.height_px -= 40 * layout.ui_scale;
  return r;
}

template <typename Predicate>
int count(const RgbaImage& image, const PixelRect& r, Predicate predicate) {
  int n = 0;
  for (int y = r.y_px; y < r.y_px + r.height_px; ++y) {
    for (int x = r.x_px; x < r.x_px + r.width_px; ++x) n += predicate(image.at(x, y)) ? 1 : 0;
  }
  return n;
}

class SceneRendererTest : public ::testing::Test {
 protected:
  SceneRendererTest() : display_(settings()), renderer_(display_), bscan_(gradient_bscan()) {
    frame_ = scene_.frame;
    frame_.bscan = {bscan_, kBscanW, kBscanH, 32.0f, 24.0f, true, false};
  }

  static DisplaySettings settings() {
    DisplaySettings s;
    s.width_px = 320;
    s.height_px = 200;
    return s;
  }

  RgbaImage draw(const FrameInput& frame) {
    display_.begin_frame();
    renderer_.draw(frame);
    display_.end_frame();
    return display_.read_pixels();
  }

  OffscreenDisplay display_;
  SceneRenderer renderer_;
  testing::SyntheticScene scene_ = testing::make_synthetic_scene(64, 64);
  std::vector<std::uint8_t> bscan_;
  FrameInput frame_;
};

TEST_F(SceneRendererTest, PanelReproducesTheBscan) {
  const RgbaImage image = draw(frame_);
  const PixelRect r = renderer_.layout().bscan_image;
  // 32 × 24 mm: the panel keeps the 4:3 aspect.
  EXPECT_NEAR(static_cast<double>(r.width_px) / r.height_px, 4.0 / 3.0, 0.04);
  for (const double fx : {0.1, 0.3, 0.5, 0.7, 0.9}) {
    for (const double fy : {0.2, 0.5, 0.8}) {
      const int px = r.x_px + static_cast<int>(fx * r.width_px);
      const int py = r.y_px + static_cast<int>(fy * r.height_px);
      // Bilinear sampling of a linear ramp gives the ramp at the pixel centre's texel position.
      const double u =
          std::clamp((px + 0.5 - r.x_px) / r.width_px * kBscanW - 0.5, 0.0, kBscanW - 1.0);
      const double v =
          std::clamp((py + 0.5 - r.y_px) / r.height_px * kBscanH - 0.5, 0.0, kBscanH - 1.0);
      const double expected = 3.0 * u + v;
      const std::uint8_t* p = image.at(px, py);
      EXPECT_NEAR(p[0], expected, 2.0) << "at fraction " << fx << "," << fy;
      EXPECT_EQ(p[0], p[1]);
      EXPECT_EQ(p[1], p[2]);
    }
  }
}

TEST_F(SceneRendererTest, ViewShowsTheMeshInDisplacementColours) {
  // Nodes on the +x half fully displaced (red), the rest at rest (blue).
  std::vector<float> displacement(scene_.displacement_mm.size());
  for (std::size_t i = 0; i < displacement.size(); ++i) {
    displacement[i] = scene_.positions_mm[3 * i] > 45.0f ? 6.0f : 0.0f;
  }
  frame_.mesh.node_displacement_mm = displacement;
  const RgbaImage image = draw(frame_);
  const PixelRect view = scene_region(renderer_.layout());
  EXPECT_GT(count(image, view, is_mesh_blue), 100);
  EXPECT_GT(count(image, view, is_mesh_red), 100);

  frame_.mesh = {};
  const RgbaImage without_mesh = draw(frame_);
  EXPECT_LT(count(without_mesh, view, is_mesh_blue), 5);
}

// Levels of detail: the finest level whose lines lie at least a few pixels apart is drawn; the
// trainee's MESH toggle hides the wireframe altogether.
TEST_F(SceneRendererTest, TheWireframeDrawsTheLevelOfDetailTheScreenCanShow) {
  frame_.mesh.node_displacement_mm = {};  // every line the ramp's blue
  const RgbaImage all_lines = draw(frame_);
  const PixelRect view = scene_region(renderer_.layout());
  const int full = count(all_lines, view, is_mesh_blue);
  ASSERT_GT(full, 100);
  const std::vector<std::uint32_t> one_line = {frame_.mesh.line_indices[0],
                                               frame_.mesh.line_indices[1]};
  // Level 0 (every line) 0.01 mm apart: too dense at any zoom; level 1, one line: drawn.
  std::vector<LineLevel> levels = {{frame_.mesh.line_indices, 0.01f}, {one_line, 1000.0f}};
  frame_.mesh.line_levels = levels;
  const int coarse = count(draw(frame_), view, is_mesh_blue);
  EXPECT_GT(coarse, 0) << "the coarse level's one line";
  EXPECT_LT(coarse, full / 10) << "the coarse level";
  // Every line 1000 mm apart: the finest level is fine enough.
  levels[0].spacing_mm = 1000.0f;
  EXPECT_EQ(count(draw(frame_), view, is_mesh_blue), full);
  frame_.view.show_mesh = false;
  EXPECT_LT(count(draw(frame_), view, is_mesh_blue), 5) << "MESH off";
}

TEST_F(SceneRendererTest, NoContactShowsTheStateAndNoBscanPixels) {
  frame_.bscan.in_contact = false;
  const RgbaImage image = draw(frame_);
  const PixelRect r = renderer_.layout().bscan_image;
  EXPECT_EQ(count(image, r, is_grey), 0);
  EXPECT_GT(count(image, r, is_red), 2 * (r.width_px + r.height_px));
  EXPECT_GT(count(image, renderer_.layout().header, is_red), 20) << "header status";
}

TEST_F(SceneRendererTest, InconsistentBscanShowsNoImageNotGarbage) {
  frame_.bscan.pixels = std::span(bscan_).first(100);  // far fewer than 64 × 48
  const RgbaImage image = draw(frame_);
  const PixelRect r = renderer_.layout().bscan_image;
  EXPECT_EQ(count(image, r, is_grey), 0);
  EXPECT_GT(count(image, r, is_amber), 2 * (r.width_px + r.height_px));
}

TEST_F(SceneRendererTest, FrozenImageIsTagged) {
  draw(frame_);
  const PixelRect& panel = renderer_.layout().bscan_panel;
  const PixelRect strip{panel.x_px, panel.y_px, panel.width_px, 20};
  EXPECT_EQ(count(draw(frame_), strip, is_amber), 0);
  frame_.bscan.frozen = true;
  EXPECT_GT(count(draw(frame_), strip, is_amber), 30);
}

// The probe source's trouble along the B-scan panel's foot, in the warning colour.
TEST_F(SceneRendererTest, TheProbeSourcesTroubleIsShownOnThePanel) {
  draw(frame_);  // lays the screen out
  const PixelRect& panel = renderer_.layout().bscan_panel;
  const PixelRect foot{panel.x_px, panel.y_px + panel.height_px - 16, panel.width_px, 16};
  EXPECT_EQ(count(draw(frame_), foot, is_red), 0);
  frame_.probe_status = "camera: no markers in view";
  EXPECT_GT(count(draw(frame_), foot, is_red), 40);
}

// The stats overlay, top right of the 3D view, only when asked for; a lost probe in red.
TEST_F(SceneRendererTest, TheStatsOverlayShowsWhenAskedFor) {
  draw(frame_);
  const PixelRect& view = renderer_.layout().view_3d;
  const PixelRect corner{view.x_px + view.width_px / 2, view.y_px + 2, view.width_px / 2 - 2, 70};
  const auto text = [](const std::uint8_t* p) { return p[0] > 120 && p[1] > 120 && p[2] > 120; };
  const int before = count(draw(frame_), corner, text);
  frame_.stats = {true, 60.0f, 14.5f, 55.0f, 3, 16.5f, "can0", true};
  const int with_stats = count(draw(frame_), corner, text);
  EXPECT_GT(with_stats, before + 100);
  EXPECT_EQ(count(draw(frame_), corner, is_red), 0);
  frame_.stats.probe_ok = false;
  EXPECT_GT(count(draw(frame_), corner, is_red), 20);
}

TEST_F(SceneRendererTest, BadMeshAndPoseAreSkippedNotDrawn) {
  std::vector<std::uint32_t> bad = scene_.lines;
  bad.back() = 1'000'000;  // past the last node
  frame_.mesh.line_indices = bad;
  frame_.probe.probe_to_patient[12] = std::numeric_limits<float>::quiet_NaN();
  frame_.scene_max_mm = {std::numeric_limits<float>::infinity(), 0.0f, 0.0f};
  const RgbaImage image = draw(frame_);
  EXPECT_LT(count(image, scene_region(renderer_.layout()), is_mesh_blue), 5);
  // The B-scan is unaffected.
  EXPECT_GT(count(image, renderer_.layout().bscan_image, is_grey), 1000);
}

TEST_F(SceneRendererTest, DrawDoesNotAllocateAfterTheFirstFrames) {
  RgbaImage image;
  const auto frame_once = [&] {
    display_.begin_frame();
    renderer_.draw(frame_);
    display_.end_frame();
    display_.read_pixels_into(image);
  };
  frame_once();
  frame_once();
  // The counter itself works: one vector, one allocation.
  ::ultrasim::testing::start_counting_allocations();
  std::vector<int> probe(16);
  EXPECT_EQ(::ultrasim::testing::stop_counting_allocations(), 1);

  ::ultrasim::testing::start_counting_allocations();
  for (int i = 0; i < 5; ++i) {
    frame_.frame_index = 100000 + i;
    frame_once();
  }
  EXPECT_EQ(::ultrasim::testing::stop_counting_allocations(), 0);
}

TEST(SceneRendererScreenshot, WritesTheKioskScreen) {
  DisplaySettings settings;  // 1280 × 720
  OffscreenDisplay display(settings);
  SceneRenderer renderer(display);
  const testing::SyntheticScene scene = testing::make_synthetic_scene();
  display.begin_frame();
  renderer.draw(scene.frame);
  display.end_frame();
  const RgbaImage image = display.read_pixels();
  EXPECT_GT(count(image, renderer.layout().bscan_image, is_grey), 100000);
  EXPECT_GT(count(image, scene_region(renderer.layout()), is_mesh_blue), 500);
  write_png(std::string(ULTRASIM_BINARY_DIR) + "/render_kiosk_screen.png", image);
}

}  // namespace
}  // namespace ultrasim::render
