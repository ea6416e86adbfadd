#pragma once

namespace ultrasim::render {

// A rectangle in screen pixels: origin at the top-left corner of the screen, y down (the order
// of RgbaImage rows).
struct PixelRect {
  int x_px = 0;
  int y_px = 0;
  int width_px = 0;
  int height_px = 0;

  bool contains(int x, int y) const {
    return x >= x_px && y >= y_px && x < x_px + width_px && y < y_px + height_px;
  }
  int center_x_px() const { return x_px + width_px / 2; }
  int center_y_px() const { return y_px + height_px / 2; }
};

// Where each part of the kiosk screen goes. The same numbers drive drawing, tests and, later,
// touch hit-testing.
struct ScreenLayout {
  PixelRect header;           // title bar across the top
  PixelRect header_controls;  // the title bar between the product name and the scan state
  PixelRect view_3d;          // left panel: tissue mesh, probe, image plane, collider
  PixelRect bscan_panel;      // right panel, black, around the B-scan and its scales
  PixelRect bscan_image;      // the B-scan itself, aspect-correct (width_mm : depth_mm)
  PixelRect depth_scale;      // strip left of bscan_image with depth ticks and cm labels
  PixelRect controls;         // the trainer's controls, along the foot of the B-scan panel
  int ui_scale = 1;  // integer pixel size of font dots and thick lines (1 up to 539 px high)
};

// Lays out a width_px × height_px screen whose B-scan covers image_width_mm × image_depth_mm
// (non-positive or non-finite extents fall back to a square image). view_fraction is the share of
// the width given to the 3D view (clamped to 0.2..0.8). Pure: any thread, no allocation.
ScreenLayout layout_screen(int width_px, int height_px, float image_width_mm, float image_depth_mm,
                           float view_fraction = 0.55f);

}  // namespace ultrasim::render
