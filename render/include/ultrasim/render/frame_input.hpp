#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>

namespace ultrasim::render {

// Everything the renderer needs for one frame, as plain views into buffers the caller owns for
// the duration of the draw call. No simulation objects cross this line (DESIGN.md §2).
// All lengths in mm, in patient (case) space: +x lateral, +y along the limb, +z depth into tissue.

struct BscanView {
  std::span<const std::uint8_t> pixels;  // row-major grey levels, row 0 at the probe face
  int width_px = 0;
  int height_px = 0;
  float width_mm = 0.0f;   // lateral extent of the image
  float depth_mm = 0.0f;   // axial extent of the image
  bool in_contact = true;  // false: the probe is off the skin, the panel shows "no contact"
  bool frozen = false;
  float gain_db = 0.0f;  // the scanner's gain, read out on the panel
};

// One level of detail of the mesh's wireframe: its lines and how far apart they lie.
struct LineLevel {
  std::span<const std::uint32_t> line_indices;  // pairs of node indices
  float spacing_mm = 0.0f;
};

struct MeshView {
  std::span<const float> node_positions_mm;     // x,y,z per node, deformed
  std::span<const std::uint32_t> line_indices;  // pairs of node indices to draw as lines
  std::span<const float> node_displacement_mm;  // |u| per node, for colouring (may be empty)
  // Coarser alternatives to line_indices, finest first (may be empty): the view draws the finest
  // whose lines stay a few pixels apart on screen, so a large mesh does not fill the panel
  // with lines the rasteriser must draw and no one can tell apart.
  std::span<const LineLevel> line_levels;
};

// A closed triangle surface (vessel, nerve, bone) embedded in the tissue, already deformed.
struct SurfaceView {
  std::span<const float> positions_mm;       // x,y,z per vertex
  std::span<const float> normals;            // x,y,z per vertex, unit; empty: flat shading
  std::span<const std::uint32_t> triangles;  // 3 vertex indices each, counter-clockwise outside
  std::array<float, 4> rgba{0.8f, 0.2f, 0.2f, 1.0f};  // colour; alpha < 1: translucent
  bool skin = false;  // the body's skin: hidden when the trainee cuts it away (ViewOptions)
};

struct ProbeView {
  // Column-major 4×4 rigid transform from the probe frame (origin at the face centre, +x along
  // the array, +y elevational, +z along the beam) to patient space.
  std::array<float, 16> probe_to_patient{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  float face_width_mm = 38.0f;
  float face_thickness_mm = 10.0f;
  float body_height_mm = 60.0f;  // drawn above the face, along -z of the probe frame
  float image_depth_mm = 40.0f;  // the imaging plane drawn below the face
  std::array<float, 3> collider_center_mm{0, 0, 0};
  float collider_radius_mm = 0.0f;  // 0: do not draw the collider
};

// The stats overlay (top right of the 3D view): how the kiosk keeps up, for the trainer and the
// service engineer. Not drawn unless `shown`.
struct StatsView {
  bool shown = false;
  float frames_per_second = 0.0f;
  float frame_p99_ms = 0.0f;
  float budget_use_percent = 0.0f;  // frame time p50 over the frame budget
  std::int64_t deadline_misses = 0;
  float probe_to_photon_p99_ms = 0.0f;
  std::string_view probe_source;  // "can0", "camera /dev/video0", ...
  bool probe_ok = true;           // the source has nothing to say (FrameInput::probe_status)
};

// How the trainee looks at the 3D view (render::TrainerUi's orbit, zoom and toggles).
struct ViewOptions {
  float azimuth_offset_deg = 0.0f;    // turned from the style's azimuth
  float elevation_offset_deg = 0.0f;  // lifted from the style's elevation
  float zoom = 1.0f;                  // > 1 closer; the framed scene at 1
  bool show_mesh = true;              // the tet mesh's wireframe
  bool show_skin = true;              // false: the skin cut away, the tissue bare
};

struct FrameInput {
  BscanView bscan;
  MeshView mesh;
  ProbeView probe;
  std::span<const SurfaceView> surfaces;       // drawn inside the tissue; may be empty
  std::array<float, 3> scene_min_mm{0, 0, 0};  // bounds of the tissue, for framing the 3D view
  std::array<float, 3> scene_max_mm{1, 1, 1};
  std::int64_t frame_index = 0;
  // Why the probe's pose is not fresh ("camera: no markers in view"), shown as a warning on the
  // B-scan panel; empty while the tracker is well.
  std::string_view probe_status;
  StatsView stats;
  ViewOptions view;
};

}  // namespace ultrasim::render
