#pragma once

// The closed surfaces of a frame (vessels, nerve, bone) as GL buffers, and their draw calls in
// the 3D view. Internal to render/.

#include <GLES3/gl3.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "programs.hpp"
#include "scene_camera.hpp"
#include "stream_buffer.hpp"
#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::render::detail {

// One slot of GL buffers per surface, by position in FrameInput::surfaces. Positions and normals
// are overwritten every frame (glBufferSubData); a surface's triangle indices are uploaded again
// only when their span's data pointer or length, or the vertex count, changes, so a caller that
// rewrites indices in place must hand over a different span. Storage grows (glBufferData) only when
// a surface grows; slots are created only when the number of surfaces grows. Render thread only.
class SurfaceLayer {
 public:
  SurfaceLayer();
  ~SurfaceLayer();
  SurfaceLayer(const SurfaceLayer&) = delete;
  SurfaceLayer& operator=(const SurfaceLayer&) = delete;

  // Uploads this frame's surfaces. A surface is skipped for the frame (drawn as absent) when it
  // has no whole triangle, an index past its last vertex, a non-finite first vertex (a cheap
  // guard; the GPU drops triangles with other non-finite vertices by itself), a non-finite
  // colour or zero alpha. Normals whose length differs from the positions' mean flat shading.
  void upload(std::span<const SurfaceView> surfaces);

  // Surfaces with alpha 1, back faces culled (closed, counter-clockwise outside: a back face is
  // always behind a front face of its own surface), depth written. Expects depth testing on.
  // show_skin false: the surfaces marked as skin are left out (cut away).
  void draw_opaque(const SurfaceProgram& program, const SceneCamera& camera,
                   bool show_skin = true) const;

  // Surfaces with alpha < 1, blended, without depth writes so that what lies behind them in the
  // same pass still shows. Each surface draws its back faces (the far wall, seen through the
  // near one) before its front faces, so a convex cross-section composes in depth order; two
  // translucent surfaces over each other compose in the order the frame lists them. Expects
  // depth testing and blending on. Call after the opaque scene.
  void draw_translucent(const SurfaceProgram& program, const SceneCamera& camera,
                        bool show_skin = true) const;

 private:
  struct Slot {
    Slot();
    ~Slot();
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;

    StreamBuffer positions;
    StreamBuffer normals;
    StreamBuffer indices;
    GLuint vao = 0;
    // The index span last uploaded and the vertex count it went with, to notice a change of
    // topology (a new surface may reuse freed memory; it rarely has the same sizes too).
    const std::uint32_t* uploaded_indices = nullptr;
    std::size_t uploaded_index_count = 0;
    std::size_t uploaded_vertex_count = 0;
    std::uint32_t max_index = 0;
    // This frame.
    GLsizei index_count = 0;  // 0: not drawn
    bool flat_shading = true;
    bool skin = false;
    std::array<float, 4> rgba{};
  };

  void use(const SurfaceProgram& program, const SceneCamera& camera) const;
  static void draw_slot(const SurfaceProgram& program, const Slot& slot);

  std::vector<std::unique_ptr<Slot>> slots_;
  std::size_t active_count_ = 0;  // slots filled this frame (the rest are stale)
  std::size_t opaque_count_ = 0;
  std::size_t translucent_count_ = 0;
};

}  // namespace ultrasim::render::detail
