#include "ultrasim/render/trainer_ui.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string_view>
#include <vector>

#include "synthetic_scene.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/scene_renderer.hpp"

namespace ultrasim::render {
namespace {

using Kind = hal::PointerEvent::Kind;

constexpr std::string_view kCases[] = {"forearm", "neck"};
constexpr std::string_view kMethods[] = {"exact fem", "msds"};

// The kiosk screen at 1280×720 with the controls over it, driven one frame at a time.
class TrainerUiTest : public ::testing::Test {
 protected:
  TrainerUiTest()
      : display_(offscreen_display_settings(1280, 720)),
        renderer_(display_),
        ui_(display_),
        bscan_(64 * 48, 90) {
    frame_ = scene_.frame;
    frame_.bscan = {bscan_, 64, 48, 38.0f, 40.0f, true, false};
    model_.tgc_db = tgc_;
    model_.case_names = kCases;
    model_.method_names = kMethods;
    model_.settings = fields_;
    run({});  // lays the controls out once, so their places are known
  }

  TrainerActions run(std::vector<hal::PointerEvent> events) {
    display_.begin_frame();
    frame_.view = ui_.view_options();
    renderer_.draw(frame_);
    const TrainerActions actions = ui_.frame(frame_, renderer_.layout(), model_, events);
    display_.end_frame();
    return actions;
  }

  // Lands, presses and releases at a point within one frame's events: the queue spreads them
  // over three frames (there, pressed, released). Returns the last frame's actions (a button
  // acts on release).
  TrainerActions tap_at(float x, float y) {
    run({{Kind::kMove, x, y, 0}, {Kind::kPress, x, y, 0}, {Kind::kRelease, x, y, 0}});
    run({});
    return run({});
  }

  // A finger, as a person does, lands a moment after what it taps appeared (a list or dialog
  // that opens is hidden in its first frame while ImGui measures it).
  TrainerActions tap(std::string_view label) {
    run({});
    const auto rect = ui_.widget_rect(label);
    EXPECT_TRUE(rect.has_value()) << label << " is not on screen";
    if (!rect) return {};
    return tap_at(static_cast<float>(rect->center_x_px()), static_cast<float>(rect->center_y_px()));
  }

  OffscreenDisplay display_;
  SceneRenderer renderer_;
  TrainerUi ui_;
  testing::SyntheticScene scene_ = testing::make_synthetic_scene(64, 64);
  std::vector<std::uint8_t> bscan_;
  std::vector<float> tgc_ = std::vector<float>(8, 0.0f);
  std::vector<SettingField> fields_ = {
      {"FEM", "fem", "pcg_iterations_per_frame", 20, 5, true},
      {"MSDS", "msds", "damping_per_stiffness_s", 0.1, 0.05, false},
      {"MSDS", "msds", "steps_per_frame", 20, 1, true},
  };
  TrainerModel model_;
  FrameInput frame_;
};

TEST_F(TrainerUiTest, EveryControlIsOnScreenInsideItsPanel) {
  const ScreenLayout& layout = renderer_.layout();
  for (const char* label : {"FREEZE", "SAVE", "CALIPER", "TGC", "GAIN -", "GAIN +", "DEPTH -",
                            "DEPTH +", "PRESS -", "PRESS +"}) {
    const auto rect = ui_.widget_rect(label);
    ASSERT_TRUE(rect) << label;
    EXPECT_TRUE(layout.controls.contains(rect->x_px, rect->y_px)) << label;
    EXPECT_FALSE(layout.bscan_image.contains(rect->center_x_px(), rect->center_y_px())) << label;
    EXPECT_GE(rect->height_px, 30) << label << " is large enough for a finger at 720 p";
  }
  for (const char* label : {"MESH", "SKIN", "ZOOM -", "ZOOM +", "RESET VIEW"}) {
    if (std::string_view(label) == "RESET VIEW") {
      const auto rect = ui_.widget_rect(label);
      ASSERT_TRUE(rect);
      EXPECT_LE(rect->x_px + rect->width_px, layout.view_3d.x_px + layout.view_3d.width_px);
    }
    const auto rect = ui_.widget_rect(label);
    ASSERT_TRUE(rect) << label;
    EXPECT_TRUE(layout.view_3d.contains(rect->x_px, rect->y_px)) << label;
  }
  for (const char* label : {"CASE", "METHOD", "SETTINGS", "SERVICE"}) {
    const auto rect = ui_.widget_rect(label);
    ASSERT_TRUE(rect) << label;
    EXPECT_TRUE(layout.header.contains(rect->center_x_px(), rect->center_y_px())) << label;
  }
  EXPECT_FALSE(ui_.widget_rect("NO SUCH BUTTON"));
}

TEST_F(TrainerUiTest, ATapWithinOneFrameStillPressesTheButtonOnce) {
  const TrainerActions actions = tap("FREEZE");
  EXPECT_TRUE(actions.toggle_freeze);
  EXPECT_FALSE(run({}).toggle_freeze) << "one tap, one toggle";
}

TEST_F(TrainerUiTest, SteppersAskForTheNextValue) {
  model_.gain_db = 6.0f;
  model_.depth_mm = 40.0f;
  EXPECT_FLOAT_EQ(tap("GAIN +").gain_db.value_or(-1), 9.0f);
  EXPECT_FLOAT_EQ(tap("GAIN -").gain_db.value_or(-1), 3.0f);
  EXPECT_FLOAT_EQ(tap("DEPTH +").depth_mm.value_or(-1), 50.0f);
  EXPECT_EQ(tap("PRESS +").compression_steps, 1);
  EXPECT_EQ(tap("PRESS -").compression_steps, -1);
  EXPECT_TRUE(tap("SAVE").save);
}

TEST_F(TrainerUiTest, ListsOpenAndPickByName) {
  EXPECT_EQ(tap("METHOD").method_index, TrainerActions::kNoChange);
  ASSERT_TRUE(ui_.widget_rect("MSDS")) << "the open list shows the methods";
  EXPECT_EQ(tap("MSDS").method_index, 1);
  run({});
  EXPECT_FALSE(ui_.widget_rect("MSDS")) << "and closes after the pick";
  tap("CASE");
  EXPECT_EQ(tap("NECK").case_index, 1);
}

TEST_F(TrainerUiTest, CalipersMeasureInImageMillimetres) {
  const PixelRect image = renderer_.layout().bscan_image;
  tap("CALIPER");
  // 10 mm and 30 mm deep, 5 mm and 20 mm from the left edge: 25 mm apart (15, 20, 25).
  const auto x_at = [&](float mm) { return image.x_px + mm / 38.0f * image.width_px; };
  const auto y_at = [&](float mm) { return image.y_px + mm / 40.0f * image.height_px; };
  tap_at(x_at(5.0f), y_at(10.0f));
  EXPECT_EQ(ui_.calipers().points, 1);
  tap_at(x_at(20.0f), y_at(30.0f));
  ASSERT_EQ(ui_.calipers().points, 2);
  const float mm_per_px = 40.0f / static_cast<float>(image.height_px);
  EXPECT_NEAR(ui_.calipers().distance_mm(), 25.0f, 1.5f * mm_per_px);
  tap("CALIPER");
  EXPECT_EQ(ui_.calipers().points, 0) << "switching the calipers off clears them";
}

TEST_F(TrainerUiTest, DraggingTheViewOrbitsAndTheWheelZooms) {
  const PixelRect v = renderer_.layout().view_3d;
  const float x = static_cast<float>(v.center_x_px()), y = static_cast<float>(v.center_y_px());
  run({{Kind::kPress, x, y, 0}});
  run({});  // the finger lands, then slides
  run({{Kind::kMove, x + 50.0f, y + 20.0f, 0}});
  run({{Kind::kMove, x + 100.0f, y + 40.0f, 0}});
  run({{Kind::kRelease, x + 100.0f, y + 40.0f, 0}});
  EXPECT_LT(ui_.view_options().azimuth_offset_deg, -10.0f);
  EXPECT_GT(ui_.view_options().elevation_offset_deg, 5.0f);
  run({{Kind::kWheel, x, y, 2.0f}});
  EXPECT_NEAR(ui_.view_options().zoom, 1.15f * 1.15f, 1e-4f);
  tap("MESH");
  tap("SKIN");
  EXPECT_FALSE(ui_.view_options().show_mesh);
  EXPECT_FALSE(ui_.view_options().show_skin);
  tap("RESET VIEW");
  EXPECT_EQ(ui_.view_options().zoom, 1.0f);
  EXPECT_TRUE(ui_.view_options().show_mesh);
}

// A device read once a frame may hand over a whole drag at once: its press, moves and release
// still reach the UI in order, one frame each, so the view turns.
TEST_F(TrainerUiTest, ADragArrivingInOneBatchStillOrbits) {
  const PixelRect v = renderer_.layout().view_3d;
  const float x = static_cast<float>(v.center_x_px()), y = static_cast<float>(v.center_y_px());
  run({{Kind::kMove, x, y, 0},
       {Kind::kPress, x, y, 0},
       {Kind::kMove, x - 60.0f, y, 0},
       {Kind::kMove, x - 120.0f, y, 0},
       {Kind::kRelease, x - 120.0f, y, 0}});
  for (int i = 0; i < 4; ++i) run({});
  EXPECT_GT(ui_.view_options().azimuth_offset_deg, 10.0f);
}

TEST_F(TrainerUiTest, ADragThatStartsOnAControlDoesNotOrbit) {
  const auto rect = ui_.widget_rect("MESH");
  ASSERT_TRUE(rect);
  const auto x = static_cast<float>(rect->center_x_px());
  const auto y = static_cast<float>(rect->center_y_px());
  run({{Kind::kMove, x, y, 0}});
  run({{Kind::kPress, x, y, 0}});
  run({{Kind::kMove, x - 200.0f, y - 200.0f, 0}});
  run({{Kind::kRelease, x - 200.0f, y - 200.0f, 0}});
  EXPECT_EQ(ui_.view_options().azimuth_offset_deg, 0.0f);
}

TEST_F(TrainerUiTest, NonFiniteCoordinatesAreDropped) {
  const float nan = std::nanf("");
  const TrainerActions actions = run({{Kind::kPress, nan, 10.0f, 0}, {Kind::kWheel, 0, 0, nan}});
  EXPECT_EQ(actions.case_index, TrainerActions::kNoChange);
  EXPECT_EQ(ui_.view_options().zoom, 1.0f);
}

TEST_F(TrainerUiTest, SettingsAreEditedWithStepsAndHandedOverOnApply) {
  tap("SETTINGS");
  EXPECT_TRUE(ui_.widget_rect("fem.pcg_iterations_per_frame +")) << "the first page shows first";
  EXPECT_FALSE(ui_.widget_rect("msds.steps_per_frame +"));
  tap("TAB MSDS");
  run({});
  ASSERT_TRUE(ui_.widget_rect("msds.steps_per_frame +"));
  tap("msds.steps_per_frame +");
  tap("msds.damping_per_stiffness_s -");
  tap("msds.damping_per_stiffness_s -");
  const TrainerActions applied = tap("APPLY");
  ASSERT_EQ(applied.settings_applied.size(), 3u);
  EXPECT_EQ(applied.settings_applied[0], 20.0) << "untouched";
  EXPECT_NEAR(applied.settings_applied[1], 0.0, 1e-12);
  EXPECT_EQ(applied.settings_applied[2], 21.0);
  ui_.settings_refused("msds.damping_per_stiffness_s: must be > 0");
  run({});
  EXPECT_TRUE(ui_.widget_rect("APPLY")) << "a refusal keeps the dialog open";
  ui_.settings_accepted();
  run({});
  EXPECT_FALSE(ui_.widget_rect("APPLY"));
}

TEST_F(TrainerUiTest, TheTgcSlidersSetTheirBand) {
  tap("TGC");
  const auto rect = ui_.widget_rect("TGC 3");
  ASSERT_TRUE(rect);
  // A touch near the slider's top asks for about +30 dB on the third band.
  const auto x = static_cast<float>(rect->center_x_px());
  const auto y = static_cast<float>(rect->y_px + 2);
  TrainerActions moved = run({{Kind::kMove, x, y, 0}, {Kind::kPress, x, y, 0}});
  if (moved.tgc_slider == TrainerActions::kNoChange) moved = run({});
  run({{Kind::kRelease, x, y, 0}});
  EXPECT_EQ(moved.tgc_slider, 2);
  EXPECT_NEAR(moved.tgc_db, 30.0f, 1.5f);
  EXPECT_EQ(moved.tgc_db, std::round(moved.tgc_db)) << "whole decibels";
}

}  // namespace
}  // namespace ultrasim::render
