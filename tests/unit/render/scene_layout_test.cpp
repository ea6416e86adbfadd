#include "ultrasim/render/scene_layout.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace ultrasim::render {
namespace {

bool inside(const PixelRect& inner, const PixelRect& outer) {
  return inner.x_px >= outer.x_px && inner.y_px >= outer.y_px &&
         inner.x_px + inner.width_px <= outer.x_px + outer.width_px &&
         inner.y_px + inner.height_px <= outer.y_px + outer.height_px;
}

TEST(SceneLayout, SplitsTheScreenAndKeepsTheImageAspect) {
  for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{320, 200}, std::pair{1920, 1080}}) {
    for (const auto& [width_mm, depth_mm] :
         {std::pair{38.0f, 40.0f}, std::pair{50.0f, 20.0f}, std::pair{20.0f, 90.0f}}) {
      const ScreenLayout l = layout_screen(w, h, width_mm, depth_mm);
      SCOPED_TRACE(testing::Message() << w << "x" << h << " " << width_mm << "x" << depth_mm);
      EXPECT_TRUE(inside(l.bscan_image, l.bscan_panel));
      EXPECT_TRUE(inside(l.depth_scale, l.bscan_panel));
      EXPECT_LE(l.view_3d.x_px + l.view_3d.width_px, l.bscan_panel.x_px);
      EXPECT_GE(l.view_3d.y_px, l.header.height_px);
      EXPECT_NEAR(l.view_3d.x_px + l.view_3d.width_px, 0.55 * w, 4.0 * l.ui_scale);
      const double aspect = static_cast<double>(l.bscan_image.width_px) / l.bscan_image.height_px;
      EXPECT_NEAR(aspect, width_mm / depth_mm, 1.5 / l.bscan_image.height_px * aspect + 0.02);
      EXPECT_EQ(l.depth_scale.x_px + l.depth_scale.width_px, l.bscan_image.x_px);
      // The trainer's controls along the panel's foot, clear of the image and its scale.
      EXPECT_TRUE(inside(l.controls, l.bscan_panel));
      EXPECT_GT(l.controls.y_px, l.bscan_image.y_px + l.bscan_image.height_px);
      EXPECT_TRUE(inside(l.header_controls, l.header));
    }
  }
}

TEST(SceneLayout, ScalesUiWithScreenHeight) {
  EXPECT_EQ(layout_screen(320, 200, 1, 1).ui_scale, 1);
  EXPECT_EQ(layout_screen(1280, 720, 1, 1).ui_scale, 2);
  EXPECT_EQ(layout_screen(1920, 1080, 1, 1).ui_scale, 3);
}

TEST(SceneLayout, BadExtentsFallBackToASquareImage) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const auto& [wm, dm] :
       {std::pair{0.0f, 40.0f}, std::pair{-1.0f, 5.0f}, std::pair{nan, 3.0f}}) {
    const ScreenLayout l = layout_screen(1280, 720, wm, dm, nan);
    EXPECT_EQ(l.bscan_image.width_px, l.bscan_image.height_px);
    EXPECT_GT(l.bscan_image.width_px, 100);
  }
}

}  // namespace
}  // namespace ultrasim::render
