#include "ultrasim/render/scene_renderer.hpp"

#include <GLES3/gl3.h>

#include <cmath>

#include "bitmap_font.hpp"
#include "bscan_panel.hpp"
#include "bscan_texture.hpp"
#include "color_batch.hpp"
#include "mat4.hpp"
#include "programs.hpp"
#include "text_buffer.hpp"
#include "textured_quads.hpp"
#include "theme.hpp"
#include "tissue_view.hpp"

namespace ultrasim::render {
namespace {

using detail::BscanState;
using detail::ColorBatch;
using detail::Rgba8;
namespace theme = detail::theme;

float positive_or(float value, float fallback) {
  return std::isfinite(value) && value > 0.0f ? value : fallback;
}

// Title bar: product mark and name on the left; the scan state and frame counter on the right;
// between them the trainer's case list, method and dialogs (render::TrainerUi).
void add_header(const ScreenLayout& layout, const FrameInput& frame, BscanState state,
                ColorBatch& over) {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& h = layout.header;
  const float w = static_cast<float>(h.width_px);
  const float hh = static_cast<float>(h.height_px);
  over.fill_rect(0.0f, hh - 1.0f, w, 1.0f, theme::kPanelBorder);

  const float text_y = 0.5f * (hh - 7.0f * s);
  float x = 6.0f * s;
  over.fill_rect(x, text_y, 3.0f * s, 7.0f * s, theme::kAccent);
  x += 7.0f * s;
  over.text(x, text_y, s, "ULTRASIM", theme::kTextPrimary);

  detail::TextBuffer counter;
  counter.append("FRAME ").append_int(frame.frame_index);
  const float counter_w = static_cast<float>(detail::text_width_dots(counter.view())) * s;
  float right = w - 6.0f * s - counter_w;
  over.text(right, text_y, s, counter.view(), theme::kTextSecondary);

  std::string_view status = "LIVE";
  Rgba8 status_colour = theme::kAccent;
  if (state == BscanState::kNoContact) {
    status = "NO CONTACT";
    status_colour = theme::kWarning;
  } else if (state == BscanState::kNoImage) {
    status = "NO IMAGE";
    status_colour = theme::kFrozen;
  } else if (frame.bscan.frozen) {
    status = "FROZEN";
    status_colour = theme::kFrozen;
  }
  const float status_w = static_cast<float>(detail::text_width_dots(status)) * s;
  right -= 12.0f * s + status_w;
  // A small lamp before the word, in its colour.
  over.fill_rect(right - 6.0f * s, text_y + 2.0f * s, 3.0f * s, 3.0f * s, status_colour);
  over.text(right, text_y, s, status, status_colour);
}

// The stats overlay, right-aligned at the top of the 3D view: one short line each.
void add_stats(const ScreenLayout& layout, const StatsView& stats, ColorBatch& over) {
  if (!stats.shown) return;
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& r = layout.view_3d;
  const float right = static_cast<float>(r.x_px + r.width_px) - 6.0f * s;
  float y = static_cast<float>(r.y_px) + 6.0f * s;
  const auto line = [&](const detail::TextBuffer& text, Rgba8 colour) {
    const float width = static_cast<float>(detail::text_width_dots(text.view())) * s;
    over.text(right - width, y, s, text.view(), colour);
    y += 10.0f * s;
  };
  detail::TextBuffer t;
  t.append_fixed(stats.frames_per_second, 0).append(" FPS");
  line(t, theme::kTextPrimary);
  t = {};
  t.append("FRAME P99 ").append_fixed(stats.frame_p99_ms, 1).append(" MS");
  line(t, theme::kTextSecondary);
  t = {};
  t.append("BUDGET ").append_fixed(stats.budget_use_percent, 0).append(" %");
  line(t, stats.budget_use_percent > 100.0f ? theme::kWarning : theme::kTextSecondary);
  t = {};
  t.append("MISSED ").append_int(stats.deadline_misses);
  line(t, theme::kTextSecondary);
  t = {};
  t.append("TO PHOTON P99 ").append_fixed(stats.probe_to_photon_p99_ms, 1).append(" MS");
  line(t, stats.probe_to_photon_p99_ms > 33.3f ? theme::kWarning : theme::kTextSecondary);
  t = {};
  t.append("PROBE ").append_upper(stats.probe_source).append(stats.probe_ok ? " OK" : " LOST");
  line(t, stats.probe_ok ? theme::kAccent : theme::kWarning);
}

void add_view_panel(const ScreenLayout& layout, ColorBatch& over) {
  const PixelRect& r = layout.view_3d;
  over.outline_rect(static_cast<float>(r.x_px), static_cast<float>(r.y_px),
                    static_cast<float>(r.width_px), static_cast<float>(r.height_px), 1.0f,
                    theme::kPanelBorder);
}

// Fills a screen rectangle with a colour by a scissored clear: the cheapest fill there is on a
// software rasteriser (no shading, no blending). Leaves the scissor test off.
void clear_rect(const PixelRect& r, Rgba8 colour, int screen_height_px) {
  const auto c = detail::to_float(colour);
  glEnable(GL_SCISSOR_TEST);
  glScissor(r.x_px, screen_height_px - (r.y_px + r.height_px), r.width_px, r.height_px);
  glClearColor(c[0], c[1], c[2], 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  glDisable(GL_SCISSOR_TEST);
}

}  // namespace

struct SceneRenderer::Impl {
  Impl(Display& d, const SceneStyle& s)
      : display(d), style(s), programs(detail::build_programs()), tissue(s) {}
  ~Impl() { detail::destroy_programs(programs); }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  Display& display;
  SceneStyle style;
  detail::Programs programs;
  ColorBatch over;  // 2D, drawn last: frames, scales, text
  detail::BscanTexture bscan_texture;
  detail::TexturedQuads quads;
  detail::TissueView tissue;
  ScreenLayout layout;
};

SceneRenderer::SceneRenderer(Display& display, const SceneStyle& style)
    : impl_(std::make_unique<Impl>(display, style)) {}

SceneRenderer::~SceneRenderer() = default;

const ScreenLayout& SceneRenderer::layout() const {
  return impl_->layout;
}

void SceneRenderer::draw(const FrameInput& frame) {
  Impl& im = *impl_;
  const int w = im.display.width_px();
  const int h = im.display.height_px();

  const BscanState state = detail::bscan_state(frame.bscan);
  // The texture takes every whole image, in contact or not, so nothing stale is ever shown once
  // contact returns; it is only drawn in the kImage state.
  const bool uploaded = detail::is_drawable(frame.bscan) && im.bscan_texture.update(frame.bscan);
  const bool show_image = state == BscanState::kImage && uploaded;
  // The panel shows the extent of what it displays: the image's own, else the probe's field.
  const float image_width_mm =
      show_image ? frame.bscan.width_mm : positive_or(frame.probe.face_width_mm, 38.0f);
  const float image_depth_mm = show_image ? frame.bscan.depth_mm
                                          : positive_or(frame.probe.image_depth_mm,
                                                        positive_or(frame.bscan.depth_mm, 40.0f));
  im.layout = layout_screen(w, h, image_width_mm, image_depth_mm, im.style.view_fraction);
  const ScreenLayout& layout = im.layout;

  // Fixed-function state this pass relies on, set every frame: other code may share the context.
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_CULL_FACE);
  glDepthMask(GL_TRUE);
  glEnable(GL_BLEND);
  // Colour blends by alpha; destination alpha stays opaque so screenshots are not see-through.
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glViewport(0, 0, w, h);
  const auto bg = detail::to_float(theme::kBackground);
  glClearColor(bg[0], bg[1], bg[2], 1.0f);
  glClearDepthf(1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  clear_rect(layout.header, theme::kHeader, h);
  clear_rect(layout.view_3d, theme::kPanel3d, h);
  clear_rect(layout.bscan_panel, theme::kPanelBscan, h);

  im.over.clear();
  add_header(layout, frame, state, im.over);
  add_view_panel(layout, im.over);
  im.tissue.add_overlay(layout, im.over);
  add_stats(layout, frame.stats, im.over);
  detail::add_bscan_overlay(frame, layout, state, image_depth_mm, im.over);

  const detail::Mat4 pixels_to_clip =
      detail::pixel_ortho(static_cast<float>(w), static_cast<float>(h));
  im.tissue.draw(frame, layout, w, h, im.programs, im.bscan_texture, show_image, im.quads);

  if (show_image) {
    const PixelRect& r = layout.bscan_image;
    const auto x0 = static_cast<float>(r.x_px);
    const auto y0 = static_cast<float>(r.y_px);
    const auto x1 = static_cast<float>(r.x_px + r.width_px);
    const auto y1 = static_cast<float>(r.y_px + r.height_px);
    glUseProgram(im.programs.image.id);
    glUniformMatrix4fv(im.programs.image.u_matrix, 1, GL_FALSE, pixels_to_clip.data());
    glUniform4f(im.programs.image.u_tint, 1.0f, 1.0f, 1.0f, 1.0f);
    im.bscan_texture.bind();
    // Opaque: the image replaces the black behind it, and blending would only cost fill rate
    // (CPU time on a software rasteriser).
    glDisable(GL_BLEND);
    // Row 0 of the B-scan (the probe face) at the top of the panel.
    im.quads.draw(1, {{{x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}, {x0, y1, 0}}},
                  {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}});
    glEnable(GL_BLEND);
  }

  glUseProgram(im.programs.colour.id);
  glUniformMatrix4fv(im.programs.colour.u_matrix, 1, GL_FALSE, pixels_to_clip.data());
  im.over.draw();
  glUseProgram(0);
}

}  // namespace ultrasim::render
