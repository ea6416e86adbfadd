#include "ultrasim/render/scene_layout.hpp"

#include <algorithm>
#include <cmath>

namespace ultrasim::render {
namespace {

// Vertical space, in ui_scale units, taken by the B-scan panel's title strip and bottom margin,
// and the width of the depth scale strip (two label digits, gap, long tick, gap).
constexpr int kTitleStripUnits = 22;
constexpr int kBottomMarginUnits = 10;
constexpr int kDepthScaleUnits = 26;
// Two rows of touch-sized buttons (render::TrainerUi) with their gaps.
constexpr int kControlsUnits = 48;

}  // namespace

ScreenLayout layout_screen(int width_px, int height_px, float image_width_mm, float image_depth_mm,
                           float view_fraction) {
  ScreenLayout layout;
  const int w = std::max(width_px, 1);
  const int h = std::max(height_px, 1);
  // Dots, strokes and margins grow in whole pixels with the screen height: 1 up to 539 px
  // (test sizes), 2 at 720 p, 3 at 1080 p.
  const int s = std::max(1, (h + 180) / 360);
  layout.ui_scale = s;
  const int margin = 4 * s;
  const int header_h = 17 * s;
  layout.header = {0, 0, w, header_h};
  // After "ULTRASIM" (its mark and name take 69 dots) up to the scan state and frame counter
  // ("NO CONTACT  FRAME 999999" with its lamp: 156 dots).
  layout.header_controls = {80 * s, 0, std::max(w - (80 + 170) * s, 0), header_h};

  const float fraction =
      std::isfinite(view_fraction) ? std::clamp(view_fraction, 0.2f, 0.8f) : 0.55f;
  const int split_x = static_cast<int>(std::lround(static_cast<float>(w) * fraction));
  const int panel_y = header_h + margin;
  const int panel_h = std::max(h - panel_y - margin, 1);
  layout.view_3d = {margin, panel_y, std::max(split_x - margin - margin / 2, 1), panel_h};
  const int right_x = split_x + margin / 2;
  layout.bscan_panel = {right_x, panel_y, std::max(w - right_x - margin, 1), panel_h};

  // The image keeps its physical aspect ratio, centred horizontally with equal strips either
  // side (the left one holds the depth scale), its top under the panel's title strip.
  const int scale_w = kDepthScaleUnits * s;
  const int avail_w = std::max(layout.bscan_panel.width_px - 2 * (scale_w + margin), 1);
  const int controls_h = kControlsUnits * s;
  layout.controls = {layout.bscan_panel.x_px + margin,
                     layout.bscan_panel.y_px + layout.bscan_panel.height_px - controls_h - margin,
                     std::max(layout.bscan_panel.width_px - 2 * margin, 1), controls_h};
  const int avail_h = std::max(
      layout.bscan_panel.height_px - (kTitleStripUnits + kBottomMarginUnits + kControlsUnits) * s,
      1);
  const bool valid_extent = std::isfinite(image_width_mm) && std::isfinite(image_depth_mm) &&
                            image_width_mm > 0.0f && image_depth_mm > 0.0f;
  const double aspect = valid_extent ? static_cast<double>(image_width_mm) / image_depth_mm : 1.0;
  int image_w = avail_w;
  int image_h = static_cast<int>(std::lround(avail_w / aspect));
  if (image_h > avail_h) {
    image_h = avail_h;
    image_w = std::max(static_cast<int>(std::lround(avail_h * aspect)), 1);
  }
  image_h = std::max(image_h, 1);
  const int image_x = layout.bscan_panel.x_px + (layout.bscan_panel.width_px - image_w) / 2;
  const int image_y = layout.bscan_panel.y_px + kTitleStripUnits * s;
  layout.bscan_image = {image_x, image_y, image_w, image_h};
  layout.depth_scale = {image_x - scale_w, image_y, scale_w, image_h};
  return layout;
}

}  // namespace ultrasim::render
