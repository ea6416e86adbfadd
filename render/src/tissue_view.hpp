#pragma once

// The left panel: the tissue mesh in 3D, the surfaces inside it (vessels, nerve, bone), the
// probe, the textured image plane under it, the collider, and the panel's legend. Internal to
// render/.

#include <GLES3/gl3.h>

#include "bscan_texture.hpp"
#include "color_batch.hpp"
#include "programs.hpp"
#include "stream_buffer.hpp"
#include "surface_layer.hpp"
#include "textured_quads.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/render/scene_layout.hpp"
#include "ultrasim/render/scene_style.hpp"

namespace ultrasim::render::detail {

struct SceneCamera;

// The wireframe's lines closer than this on screen are too dense to tell apart: the view draws
// a coarser level of detail.
inline constexpr float kMinLineSpacingPx = 10.0f;

// The mesh's lines to draw in a viewport `viewport_height_px` high: the finest level of detail
// whose spacing at the framed centre is at least kMinLineSpacingPx (the coarsest if none is),
// or line_indices when the mesh has no levels. Pure.
std::span<const std::uint32_t> lines_for_screen(const MeshView& mesh, const SceneCamera& camera,
                                                int viewport_height_px);

// Render thread only. After the first frame draw() allocates nothing unless the mesh grows or
// the frame brings more surfaces than any frame before.
class TissueView {
 public:
  explicit TissueView(const SceneStyle& style);
  ~TissueView();
  TissueView(const TissueView&) = delete;
  TissueView& operator=(const TissueView&) = delete;

  // Adds the panel's 2D parts (title, colour bar) to the overlay batch, in screen pixels.
  void add_overlay(const ScreenLayout& layout, ColorBatch& overlay) const;

  // Draws the 3D scene into layout.view_3d of a screen screen_height_px high. show_image: the
  // texture holds this frame's B-scan and the probe is in contact. Leaves the viewport, scissor
  // and depth test as it found them (full screen, off, off).
  void draw(const FrameInput& frame, const ScreenLayout& layout, int screen_width_px,
            int screen_height_px, const Programs& programs, const BscanTexture& texture,
            bool show_image, TexturedQuads& quads);

 private:
  // Uploads the mesh; returns the number of indices to draw (0: nothing valid to draw).
  GLsizei upload_mesh(const MeshView& mesh);
  // Bounds and collider into batch_ (the probe is added by draw, which knows the camera).
  void build_geometry(const FrameInput& frame);

  SceneStyle style_;
  StreamBuffer positions_;
  StreamBuffer displacements_;
  StreamBuffer indices_;
  GLuint mesh_vao_ = 0;
  SurfaceLayer surfaces_;
  ColorBatch batch_;
};

}  // namespace ultrasim::render::detail
