#include "tissue_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "bitmap_font.hpp"
#include "colour_ramp.hpp"
#include "scene_camera.hpp"
#include "text_buffer.hpp"
#include "theme.hpp"

namespace ultrasim::render::detail {
namespace {

constexpr int kRingSegments = 48;

Rgba8 shade(Rgba8 base, float factor) {
  const auto scale = [factor](std::uint8_t v) {
    return static_cast<std::uint8_t>(std::clamp(static_cast<float>(v) * factor, 0.0f, 255.0f));
  };
  return {scale(base.r), scale(base.g), scale(base.b), base.a};
}

Rgba8 to_rgba8(const std::array<float, 3>& c) {
  return {static_cast<std::uint8_t>(std::lround(c[0] * 255.0f)),
          static_cast<std::uint8_t>(std::lround(c[1] * 255.0f)),
          static_cast<std::uint8_t>(std::lround(c[2] * 255.0f)), 255};
}

bool all_finite(const std::array<float, 16>& m) {
  return std::all_of(m.begin(), m.end(), [](float v) { return std::isfinite(v); });
}

float positive_or(float value, float fallback) {
  return std::isfinite(value) && value > 0.0f ? value : fallback;
}

// One segment of the probe: a frustum between two rectangles across the probe axis, at probe
// depths z0 (nearer the face) and z1, with half-extents (x, y) at each end. Faces are flat-shaded
// by a light from over the viewer's shoulder; edges drawn dark on top.
struct ProbeSegment {
  float z0, z1;
  float half_x0, half_y0;
  float half_x1, half_y1;
  Rgba8 colour;
  bool cap_bottom;  // the face end (the lens) is closed
  bool cap_top;
};

class ProbeBuilder {
 public:
  ProbeBuilder(const Mat4& probe_to_patient, const Vec3& light_dir, ColorBatch& batch)
      : m_(probe_to_patient), light_(light_dir), batch_(batch) {}

  void segment(const ProbeSegment& s) {
    const std::array<Vec3, 4> bottom = rectangle(s.half_x0, s.half_y0, s.z0);
    const std::array<Vec3, 4> top = rectangle(s.half_x1, s.half_y1, s.z1);
    const Vec3 centre = transform_point(m_, {0.0f, 0.0f, 0.5f * (s.z0 + s.z1)});
    for (int i = 0; i < 4; ++i) {
      const int j = (i + 1) % 4;
      face({bottom[i], bottom[j], top[j], top[i]}, centre, s.colour);
      batch_.line(bottom[i], top[i], theme::kProbeEdge);
      batch_.line(bottom[i], bottom[j], theme::kProbeEdge);
      batch_.line(top[i], top[j], theme::kProbeEdge);
    }
    if (s.cap_bottom) face(bottom, centre, theme::kProbeEdge);
    if (s.cap_top) face(top, centre, s.colour);
  }

  // A flat plate just outside the probe's -x side: the orientation mark. By convention it sits
  // on the side shown at the left of the B-scan (lateral u = 0 is probe -x).
  void marker(float half_x, float half_y, float z0, float z1) {
    const float x = -half_x - 0.4f;
    const std::array<Vec3, 4> plate = {
        transform_point(m_, {x, -half_y, z0}), transform_point(m_, {x, half_y, z0}),
        transform_point(m_, {x, half_y, z1}), transform_point(m_, {x, -half_y, z1})};
    const Vec3 centre = transform_point(m_, {0.0f, 0.0f, 0.5f * (z0 + z1)});
    face(plate, centre, theme::kProbeMarker);
  }

 private:
  std::array<Vec3, 4> rectangle(float hx, float hy, float z) const {
    return {transform_point(m_, {-hx, -hy, z}), transform_point(m_, {hx, -hy, z}),
            transform_point(m_, {hx, hy, z}), transform_point(m_, {-hx, hy, z})};
  }

  void face(const std::array<Vec3, 4>& q, const Vec3& solid_centre, Rgba8 colour) {
    Vec3 normal = normalized(cross(q[1] - q[0], q[3] - q[0]));
    const Vec3 face_centre = (q[0] + q[1] + q[2] + q[3]) * 0.25f;
    if (dot(normal, face_centre - solid_centre) < 0.0f) normal = normal * -1.0f;
    const float lit = 0.38f + 0.62f * std::max(dot(normal, light_), 0.0f);
    batch_.quad(q[0], q[1], q[2], q[3], shade(colour, lit));
  }

  Mat4 m_;
  Vec3 light_;
  ColorBatch& batch_;
};

void add_box_edges(ColorBatch& batch, const Vec3& lo, const Vec3& hi, Rgba8 colour) {
  const auto corner = [&](int i) {
    return Vec3{(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]};
  };
  for (int i = 0; i < 8; ++i) {
    for (int bit = 1; bit < 8; bit <<= 1) {
      if ((i & bit) == 0) batch.line(corner(i), corner(i | bit), colour);
    }
  }
}

void add_ring(ColorBatch& batch, const Vec3& centre, const Vec3& u, const Vec3& v, float radius,
              Rgba8 colour) {
  constexpr float kStep = 2.0f * std::numbers::pi_v<float> / kRingSegments;
  Vec3 previous = centre + u * radius;
  for (int i = 1; i <= kRingSegments; ++i) {
    const float angle = kStep * static_cast<float>(i);
    const Vec3 next = centre + u * (radius * std::cos(angle)) + v * (radius * std::sin(angle));
    batch.line(previous, next, colour);
    previous = next;
  }
}

// Physical extent of the image plane drawn under the probe: the B-scan's own when it is shown
// (so the texture is to scale), else the face width and the probe's imaging depth.
struct PlaneExtent {
  float width_mm;
  float depth_mm;
};

PlaneExtent plane_extent(const FrameInput& frame, bool show_image) {
  if (show_image) return {frame.bscan.width_mm, frame.bscan.depth_mm};
  const float width = positive_or(frame.probe.face_width_mm, 38.0f);
  const float depth =
      positive_or(frame.probe.image_depth_mm, positive_or(frame.bscan.depth_mm, 40.0f));
  return {width, depth};
}

std::array<Vec3, 4> plane_corners(const Mat4& m, PlaneExtent e) {
  const float hw = 0.5f * e.width_mm;
  // Fan order; u runs with probe +x, v with depth (row 0 of the B-scan at the face).
  return {transform_point(m, {-hw, 0.0f, 0.0f}), transform_point(m, {hw, 0.0f, 0.0f}),
          transform_point(m, {hw, 0.0f, e.depth_mm}), transform_point(m, {-hw, 0.0f, e.depth_mm})};
}

}  // namespace

TissueView::TissueView(const SceneStyle& style)
    : style_(style),
      positions_(GL_ARRAY_BUFFER),
      displacements_(GL_ARRAY_BUFFER),
      indices_(GL_ELEMENT_ARRAY_BUFFER) {
  glGenVertexArrays(1, &mesh_vao_);
  glBindVertexArray(mesh_vao_);
  positions_.bind();
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  displacements_.bind();
  glVertexAttribPointer(1, 1, GL_FLOAT, GL_FALSE, sizeof(float), nullptr);
  // The element buffer binding is part of the VAO's state.
  indices_.bind();
  glBindVertexArray(0);
}

TissueView::~TissueView() {
  glDeleteVertexArrays(1, &mesh_vao_);
}

GLsizei TissueView::upload_mesh(const MeshView& mesh) {
  const std::size_t node_count = mesh.node_positions_mm.size() / 3;
  const std::size_t index_count = mesh.line_indices.size() & ~std::size_t{1};
  if (node_count == 0 || index_count == 0) return 0;
  // An index past the last node would make the GPU read outside the buffer: skip the mesh.
  const std::uint32_t max_index =
      *std::max_element(mesh.line_indices.begin(), mesh.line_indices.begin() + index_count);
  if (max_index >= node_count) return 0;

  glBindVertexArray(mesh_vao_);
  positions_.upload(mesh.node_positions_mm.data(), node_count * 3 * sizeof(float));
  if (mesh.node_displacement_mm.size() == node_count) {
    displacements_.upload(mesh.node_displacement_mm.data(), node_count * sizeof(float));
    glEnableVertexAttribArray(1);
  } else {
    // No per-node displacement: every node reads the constant 0 (the ramp's blue).
    glDisableVertexAttribArray(1);
    glVertexAttrib1f(1, 0.0f);
  }
  indices_.upload(mesh.line_indices.data(), index_count * sizeof(std::uint32_t));
  glBindVertexArray(0);
  return static_cast<GLsizei>(index_count);
}

void TissueView::add_overlay(const ScreenLayout& layout, ColorBatch& overlay) const {
  const auto s = static_cast<float>(layout.ui_scale);
  const PixelRect& r = layout.view_3d;
  const float x = static_cast<float>(r.x_px) + 6.0f * s;
  overlay.text(x, static_cast<float>(r.y_px) + 6.0f * s, s, "PATIENT 3D", theme::kTextSecondary);

  // Colour bar, bottom left: the ramp in four linear pieces, exactly as the shader blends it.
  const float bar_w = 72.0f * s;
  const float bar_h = 4.0f * s;
  const float label_h = 7.0f * s;
  const float bar_y =
      static_cast<float>(r.y_px + r.height_px) - 6.0f * s - label_h - 3.0f * s - bar_h;
  overlay.text(x, bar_y - 3.0f * s - label_h, s, "DISPLACEMENT", theme::kTextSecondary);
  const float piece = bar_w / (kRampStops - 1);
  for (int i = 0; i + 1 < kRampStops; ++i) {
    overlay.gradient_rect(x + piece * static_cast<float>(i), bar_y, piece, bar_h,
                          to_rgba8(kRamp[i]), to_rgba8(kRamp[i + 1]));
  }
  const float label_y = bar_y + bar_h + 3.0f * s;
  overlay.text(x, label_y, s, "0", theme::kTextSecondary);
  const float full_scale = style_.displacement_full_scale_mm;
  TextBuffer label;
  label.append_fixed(full_scale, std::nearbyint(full_scale) == full_scale ? 0 : 1).append(" MM");
  const float label_w = static_cast<float>(text_width_dots(label.view())) * s;
  overlay.text(x + bar_w - label_w, label_y, s, label.view(), theme::kTextSecondary);
}

void TissueView::build_geometry(const FrameInput& frame) {
  batch_.clear();
  if (style_.show_scene_bounds) {
    add_box_edges(batch_, {frame.scene_min_mm[0], frame.scene_min_mm[1], frame.scene_min_mm[2]},
                  {frame.scene_max_mm[0], frame.scene_max_mm[1], frame.scene_max_mm[2]},
                  theme::kBounds);
  }
  const ProbeView& probe = frame.probe;
  if (probe.collider_radius_mm > 0.0f && std::isfinite(probe.collider_radius_mm)) {
    const Vec3 c{probe.collider_center_mm[0], probe.collider_center_mm[1],
                 probe.collider_center_mm[2]};
    const float r = probe.collider_radius_mm;
    add_ring(batch_, c, {1, 0, 0}, {0, 1, 0}, r, theme::kFrozen);
    add_ring(batch_, c, {1, 0, 0}, {0, 0, 1}, r, theme::kFrozen);
    add_ring(batch_, c, {0, 1, 0}, {0, 0, 1}, r, theme::kFrozen);
  }
}

std::span<const std::uint32_t> lines_for_screen(const MeshView& mesh, const SceneCamera& camera,
                                                int viewport_height_px) {
  // Pixels per mm at the framed centre: the projection's focal term (1 / tan(fov / 2)) over the
  // distance, across half the viewport's height.
  const float px_per_mm = 0.5f * static_cast<float>(viewport_height_px) * camera.projection[5] /
                          std::max(camera.target_distance_mm, 1e-3f);
  for (const LineLevel& level : mesh.line_levels) {
    if (level.spacing_mm * px_per_mm >= kMinLineSpacingPx) return level.line_indices;
  }
  return mesh.line_levels.empty() ? mesh.line_indices : mesh.line_levels.back().line_indices;
}

void TissueView::draw(const FrameInput& frame, const ScreenLayout& layout, int screen_width_px,
                      int screen_height_px, const Programs& programs, const BscanTexture& texture,
                      bool show_image, TexturedQuads& quads) {
  const PixelRect& r = layout.view_3d;
  const int gl_y = screen_height_px - (r.y_px + r.height_px);
  glViewport(r.x_px, gl_y, r.width_px, r.height_px);
  glEnable(GL_SCISSOR_TEST);
  glScissor(r.x_px, gl_y, r.width_px, r.height_px);
  glClear(GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);

  const ProbeView& probe = frame.probe;
  const float body_height = positive_or(probe.body_height_mm, 60.0f);
  // The trainee's orbit turns the style's viewpoint; not-finite offsets leave it as styled.
  SceneStyle orbit = style_;
  const ViewOptions& view = frame.view;
  if (std::isfinite(view.azimuth_offset_deg)) orbit.camera_azimuth_deg += view.azimuth_offset_deg;
  if (std::isfinite(view.elevation_offset_deg)) {
    orbit.camera_elevation_deg += view.elevation_offset_deg;
  }
  const SceneCamera camera =
      frame_scene(frame.scene_min_mm, frame.scene_max_mm, body_height, orbit,
                  static_cast<float>(r.width_px) / static_cast<float>(r.height_px), view.zoom);
  const Mat4 view_projection = multiply(camera.projection, camera.view);

  // Mesh lines first: the opaque bulk of the scene (and on a software rasteriser much of its
  // cost: not even uploaded when the trainee hides it).
  MeshView mesh = frame.mesh;
  mesh.line_indices = lines_for_screen(frame.mesh, camera, r.height_px);
  if (const GLsizei index_count = view.show_mesh ? upload_mesh(mesh) : 0; index_count > 0) {
    glUseProgram(programs.mesh.id);
    glUniformMatrix4fv(programs.mesh.u_view, 1, GL_FALSE, camera.view.data());
    glUniformMatrix4fv(programs.mesh.u_projection, 1, GL_FALSE, camera.projection.data());
    glUniform1f(programs.mesh.u_inv_full_scale_per_mm,
                1.0f / positive_or(style_.displacement_full_scale_mm, 5.0f));
    glUniform1f(programs.mesh.u_fog_near_mm, camera.target_distance_mm - camera.framed_radius_mm);
    glUniform1f(programs.mesh.u_fog_far_mm, camera.target_distance_mm + camera.framed_radius_mm);
    const auto fog = to_float(theme::kPanel3d);
    glUniform3f(programs.mesh.u_fog_colour, fog[0], fog[1], fog[2]);
    glBindVertexArray(mesh_vao_);
    glDrawElements(GL_LINES, index_count, GL_UNSIGNED_INT, nullptr);
    glBindVertexArray(0);
  }

  // Opaque surfaces inside the tissue: depth-tested against the lines, so the wireframe in front
  // of a vessel crosses it and the wireframe behind it is hidden ("under the skin").
  surfaces_.upload(frame.surfaces);
  surfaces_.draw_opaque(programs.surface, camera, view.show_skin);

  // Bounds, collider, probe and the plane's frame.
  build_geometry(frame);
  const bool probe_ok = all_finite(probe.probe_to_patient);
  const Mat4& m = probe.probe_to_patient;
  PlaneExtent extent{};
  if (probe_ok) {
    const float face_w = positive_or(probe.face_width_mm, 38.0f);
    const float face_t = positive_or(probe.face_thickness_mm, 10.0f);
    const float head_h = 0.22f * body_height;
    const float neck_h = 0.40f * body_height;
    const float grip_hx = 0.30f * face_w;
    const float grip_hy = 0.42f * face_t;
    // Light from over the viewer's shoulder, a little from above.
    const Vec3 light = normalized(camera.eye_mm - transform_point(m, {0, 0, 0}) +
                                  Vec3{0.0f, 0.0f, -0.5f * camera.target_distance_mm});
    ProbeBuilder builder(m, light, batch_);
    builder.segment({0.0f, -head_h, 0.5f * face_w, 0.5f * face_t, 0.5f * face_w, 0.5f * face_t,
                     theme::kProbeHead, true, false});
    builder.segment({-head_h, -neck_h, 0.5f * face_w, 0.5f * face_t, grip_hx, grip_hy,
                     theme::kProbeBody, false, false});
    builder.segment({-neck_h, -body_height, grip_hx, grip_hy, grip_hx, grip_hy, theme::kProbeBody,
                     false, true});
    builder.marker(0.5f * face_w, 0.22f * face_t, -0.8f * head_h, -0.25f * head_h);

    extent = plane_extent(frame, show_image);
    const std::array<Vec3, 4> corners = plane_corners(m, extent);
    const Rgba8 frame_colour = show_image ? theme::kAccent : with_alpha(theme::kAccent, 110);
    for (int i = 0; i < 4; ++i) batch_.line(corners[i], corners[(i + 1) % 4], frame_colour);
  }
  glUseProgram(programs.colour.id);
  glUniformMatrix4fv(programs.colour.u_matrix, 1, GL_FALSE, view_projection.data());
  // Push the probe's faces back a little so its edge lines win the depth test.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(1.0f, 1.0f);
  batch_.draw();
  glDisable(GL_POLYGON_OFFSET_FILL);

  // Translucent surfaces after everything opaque, so what lies behind them is already there to
  // show through; before the image plane, which is translucent too and drawn last.
  surfaces_.draw_translucent(programs.surface, camera, view.show_skin);

  // The B-scan on its plane, translucent so the mesh behind it still shows; drawn last, without
  // depth writes, so it does not hide what lies in front of it.
  if (probe_ok && show_image) {
    glUseProgram(programs.image.id);
    glUniformMatrix4fv(programs.image.u_matrix, 1, GL_FALSE, view_projection.data());
    glUniform4f(programs.image.u_tint, 0.92f, 1.0f, 1.0f, 0.85f);
    texture.bind();
    glDepthMask(GL_FALSE);
    quads.draw(0, plane_corners(m, extent), {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}});
    glDepthMask(GL_TRUE);
  }

  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, screen_width_px, screen_height_px);
}

}  // namespace ultrasim::render::detail
