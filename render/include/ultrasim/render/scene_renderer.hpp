#pragma once

#include <memory>

#include "ultrasim/render/display.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/render/scene_layout.hpp"
#include "ultrasim/render/scene_style.hpp"

namespace ultrasim::render {

// Draws the kiosk screen from a FrameInput in one pass with GLES 3.0: a title bar; on the left a
// 3D view of the tissue mesh (lines coloured by displacement, blue → red), the closed surfaces
// inside it (vessels, nerve, bone: lit by a headlight, in their own colour, seen through the
// wireframe), the probe, the image plane textured with the B-scan and the collider; on the right
// the B-scan, aspect-correct on black, with a depth scale in cm, a "no contact" state and a
// "frozen" tag.
//
// Render thread only (the thread that owns the Display's context). Must be destroyed before its
// Display. After the first frame, draw() allocates nothing as long as the mesh, the B-scan size,
// the line count, the number of surfaces and each surface's size do not grow.
class SceneRenderer {
 public:
  // Compiles the shaders (GLSL ES 3.00) and creates the GL objects. Throws std::runtime_error with
  // the shader or program info log when compiling or linking fails. Allocates.
  explicit SceneRenderer(Display& display, const SceneStyle& style = {});
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  // Draws one frame into the framebuffer the Display has bound (call between begin_frame and
  // end_frame). Inconsistent input is drawn as absent rather than as garbage: a B-scan whose
  // pixel span is shorter than width_px × height_px shows "no image", mesh indices beyond the node
  // count skip the mesh, a displacement span of the wrong length draws the mesh in one colour; a
  // surface with an index beyond its vertices, a non-finite first vertex or colour is skipped,
  // and one whose normals span has the wrong length is flat-shaded. A surface's triangle indices
  // are uploaded again only when their span's data pointer or length or its vertex count changes
  // (indices rewritten in place must come in a different span).
  void draw(const FrameInput& frame);

  // The layout used by the last draw() (all zero before the first).
  const ScreenLayout& layout() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ultrasim::render
