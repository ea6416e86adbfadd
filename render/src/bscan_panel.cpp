#include "bscan_panel.hpp"

#include <algorithm>
#include <cmath>

#include "bitmap_font.hpp"
#include "bscan_texture.hpp"
#include "text_buffer.hpp"
#include "theme.hpp"

namespace ultrasim::render::detail {
namespace {

constexpr Rgba8 kWarningSoft{236, 150, 142};  // reddish, never grey: tests tell it from B-scan

float text_width(std::string_view text, float dot_px) {
  return static_cast<float>(text_width_dots(text)) * dot_px;
}

// Ticks every 5 mm (short) and 10 mm (long) and labels in whole cm, thinned when the scale is
// too small to keep them apart.
void add_depth_scale(const ScreenLayout& layout, float depth_mm, ColorBatch& over) {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& image = layout.bscan_image;
  const float top = static_cast<float>(image.y_px);
  const float height = static_cast<float>(image.height_px);
  const float px_per_mm = height / depth_mm;
  const float axis_x = static_cast<float>(image.x_px) - 3.0f * s;
  over.fill_rect(axis_x, top, s, height, theme::kScale);

  const bool minor_ticks = 5.0f * px_per_mm >= 4.0f * s;
  int major_step_mm = 10;
  while (static_cast<float>(major_step_mm) * px_per_mm < 4.0f * s) major_step_mm *= 2;
  int label_step_cm = 1;
  while (static_cast<float>(label_step_cm) * 10.0f * px_per_mm < 11.0f * s) {
    label_step_cm = label_step_cm == 1 ? 2 : label_step_cm == 2 ? 5 : label_step_cm * 2;
  }

  const int last_mm = static_cast<int>(std::floor(depth_mm + 1e-3f));
  for (int d = 0; d <= last_mm; d += 5) {
    const bool major = d % major_step_mm == 0;
    if (!major && (!minor_ticks || d % 10 == 0)) continue;
    // Keep the tick at the very bottom inside the image's height.
    const float y = std::min(top + static_cast<float>(d) * px_per_mm, top + height - s);
    const float length = major ? 6.0f * s : 3.0f * s;
    over.fill_rect(axis_x - length, y, length, s, theme::kScale);
    if (major && d % (label_step_cm * 10) == 0) {
      TextBuffer label;
      label.append_int(d / 10);
      const float label_x = axis_x - 6.0f * s - 3.0f * s - text_width(label.view(), s);
      const float label_y = std::min(y - 3.0f * s, top + height - 7.0f * s);
      over.text(label_x, label_y, s, label.view(), theme::kScale);
    }
  }
  // Unit under the scale's labels.
  over.text(axis_x - 9.0f * s - text_width("CM", s), top + height + 4.0f * s, s, "CM",
            theme::kTextSecondary);
}

// Ticks every 10 mm along the bottom edge, from the centre line outwards.
void add_lateral_ticks(const ScreenLayout& layout, float width_mm, ColorBatch& over) {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& image = layout.bscan_image;
  const float px_per_mm = static_cast<float>(image.width_px) / width_mm;
  if (10.0f * px_per_mm < 4.0f * s) return;
  const float centre_x = static_cast<float>(image.x_px) + 0.5f * static_cast<float>(image.width_px);
  const float y = static_cast<float>(image.y_px + image.height_px) + s;
  const int count = static_cast<int>(std::floor(0.5f * width_mm / 10.0f + 1e-3f));
  for (int k = -count; k <= count; ++k) {
    const float x = centre_x + static_cast<float>(k) * 10.0f * px_per_mm - 0.5f * s;
    over.fill_rect(x, y, s, (k == 0 ? 4.0f : 2.0f) * s, theme::kScale);
  }
}

// Dark image area, red frame and cross, and a message: unmistakably "nothing here", never a
// stale or garbage image.
void add_empty_state(const ScreenLayout& layout, BscanState state, ColorBatch& over) {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& r = layout.bscan_image;
  const float x = static_cast<float>(r.x_px);
  const float y = static_cast<float>(r.y_px);
  const float w = static_cast<float>(r.width_px);
  const float h = static_cast<float>(r.height_px);
  const bool no_contact = state == BscanState::kNoContact;
  const Rgba8 colour = no_contact ? theme::kWarning : theme::kFrozen;
  over.fill_rect(x, y, w, h, theme::kPanelBscan);
  const Rgba8 cross = with_alpha(colour, 90);
  over.stroke(x, y, x + w, y + h, s, cross);
  over.stroke(x + w, y, x, y + h, s, cross);
  over.outline_rect(x, y, w, h, 2.0f * s, colour);

  const std::string_view message = no_contact ? "NO CONTACT" : "NO IMAGE";
  const std::string_view hint = no_contact ? "PLACE THE PROBE ON THE SKIN" : "";
  // Largest dot size (up to 2 units) at which the message fits with a margin.
  const float fit = std::floor((w - 12.0f * s) / static_cast<float>(text_width_dots(message)));
  const float dot = std::clamp(fit, 1.0f, 2.0f * s);
  const bool show_hint = !hint.empty() && text_width(hint, s) + 16.0f * s <= w;
  const float box_w =
      std::max(text_width(message, dot), show_hint ? text_width(hint, s) : 0.0f) + 12.0f * s;
  const float box_h = 7.0f * dot + 12.0f * s + (show_hint ? 11.0f * s : 0.0f);
  const float box_x = x + 0.5f * (w - box_w);
  const float box_y = y + 0.5f * (h - box_h);
  over.fill_rect(box_x, box_y, box_w, box_h, theme::kPanelBscan);
  over.outline_rect(box_x, box_y, box_w, box_h, s, colour);
  over.text(x + 0.5f * (w - text_width(message, dot)), box_y + 6.0f * s, dot, message, colour);
  if (show_hint) {
    over.text(x + 0.5f * (w - text_width(hint, s)), box_y + 6.0f * s + 7.0f * dot + 5.0f * s, s,
              hint, kWarningSoft);
  }
}

}  // namespace

BscanState bscan_state(const BscanView& bscan) {
  if (!bscan.in_contact) return BscanState::kNoContact;
  return is_drawable(bscan) ? BscanState::kImage : BscanState::kNoImage;
}

void add_bscan_overlay(const FrameInput& frame, const ScreenLayout& layout, BscanState state,
                       float depth_mm, ColorBatch& over) {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& p = layout.bscan_panel;
  const float px = static_cast<float>(p.x_px);
  const float py = static_cast<float>(p.y_px);
  const float pw = static_cast<float>(p.width_px);
  over.outline_rect(px, py, pw, static_cast<float>(p.height_px), 1.0f, theme::kPanelBorder);

  // Title strip: mode and frozen tag on the left, depth on the right.
  const float text_y = py + 6.0f * s;
  over.text(px + 6.0f * s, text_y, s, "B-MODE", theme::kTextPrimary);
  const float title_end = px + 6.0f * s + text_width("B-MODE", s);
  float tag_end = title_end;
  if (frame.bscan.frozen && state == BscanState::kImage) {
    const float tag_w = text_width("FROZEN", s) + 8.0f * s;
    const float tag_x = title_end + 6.0f * s;
    over.fill_rect(tag_x, text_y - 3.0f * s, tag_w, 13.0f * s, theme::kFrozen);
    over.text(tag_x + 4.0f * s, text_y, s, "FROZEN", theme::kPanelBscan);
    tag_end = tag_x + tag_w;
  }
  // "GAIN +0 DB  DEPTH 4.0 CM" where there is room, else just "4.0 CM".
  TextBuffer depth_label;
  const float gain_db = std::isfinite(frame.bscan.gain_db) ? frame.bscan.gain_db : 0.0f;
  depth_label.append("GAIN ")
      .append(gain_db < 0.0f ? "-" : "+")
      .append_fixed(std::abs(gain_db), 0)
      .append(" DB  DEPTH ")
      .append_fixed(depth_mm / 10.0f, 1)
      .append(" CM");
  std::string_view depth_text = depth_label.view();
  const auto fits = [&](std::string_view text) {
    return px + pw - 6.0f * s - text_width(text, s) >= tag_end + 6.0f * s;
  };
  if (!fits(depth_text)) depth_text.remove_prefix(depth_text.find("DEPTH"));
  if (!fits(depth_text)) depth_text.remove_prefix(6);
  over.text(px + pw - 6.0f * s - text_width(depth_text, s), text_y, s, depth_text,
            theme::kTextSecondary);

  // Orientation mark above the image's left edge: the side of the probe's marker (probe -x).
  const PixelRect& image = layout.bscan_image;
  over.fill_rect(static_cast<float>(image.x_px), static_cast<float>(image.y_px) - 5.0f * s,
                 3.0f * s, 3.0f * s, theme::kAccent);

  // Grey map bar right of the image, white at the top: what each grey level on screen is.
  const float bar_h = std::min(64.0f * s, 0.5f * static_cast<float>(image.height_px));
  const float bar_x = static_cast<float>(image.x_px + image.width_px) + 6.0f * s;
  const float bar_y = static_cast<float>(image.y_px);
  over.vertical_gradient_rect(bar_x, bar_y, 4.0f * s, bar_h, {255, 255, 255, 255}, {0, 0, 0, 255});
  over.outline_rect(bar_x - 1.0f, bar_y - 1.0f, 4.0f * s + 2.0f, bar_h + 2.0f, 1.0f,
                    theme::kPanelBorder);

  // The tracker's trouble, along the panel's foot: the trainee sees why the image stopped
  // following the probe.
  if (!frame.probe_status.empty()) {
    TextBuffer status;
    status.append("PROBE: ").append_upper(frame.probe_status);
    const float bottom = py + static_cast<float>(p.height_px);
    over.fill_rect(px + 1.0f, bottom - 16.0f * s, pw - 2.0f, 15.0f * s, theme::kPanelBscan);
    over.text(px + 6.0f * s, bottom - 12.0f * s, s, status.view(), theme::kWarning);
  }

  add_depth_scale(layout, depth_mm, over);
  if (state == BscanState::kImage) {
    add_lateral_ticks(layout, frame.bscan.width_mm, over);
  } else {
    add_empty_state(layout, state, over);
  }
}

}  // namespace ultrasim::render::detail
