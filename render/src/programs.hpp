#pragma once

// The renderer's four GLSL ES 3.00 programs, compiled and linked once at start-up. Internal to
// render/.

#include <GLES3/gl3.h>

namespace ultrasim::render::detail {

// Vertex-coloured geometry (ColorBatch): 3D with the camera matrix, 2D with a pixel matrix.
struct ColourProgram {
  GLuint id = 0;
  GLint u_matrix = -1;
};

// Mesh lines coloured by displacement magnitude, dimmed with distance for depth.
struct MeshProgram {
  GLuint id = 0;
  GLint u_view = -1;
  GLint u_projection = -1;
  GLint u_inv_full_scale_per_mm = -1;
  GLint u_fog_near_mm = -1;
  GLint u_fog_far_mm = -1;
  GLint u_fog_colour = -1;
};

// A grey single-channel texture (the B-scan) on a quad, multiplied by a tint.
struct ImageProgram {
  GLuint id = 0;
  GLint u_matrix = -1;
  GLint u_tint = -1;
};

// Closed surfaces (vessels, nerve, bone) in one colour, lit by a headlight at the eye: Lambert
// plus a little ambient. u_flat_shading: take the face normal from screen-space derivatives of
// the view position instead of the per-vertex normal attribute.
struct SurfaceProgram {
  GLuint id = 0;
  GLint u_view = -1;
  GLint u_projection = -1;
  GLint u_colour = -1;
  GLint u_flat_shading = -1;
};

struct Programs {
  ColourProgram colour;
  MeshProgram mesh;
  ImageProgram image;
  SurfaceProgram surface;
};

// Builds all four; throws std::runtime_error with the shader log on failure. Render thread.
Programs build_programs();
void destroy_programs(Programs& programs);

}  // namespace ultrasim::render::detail
