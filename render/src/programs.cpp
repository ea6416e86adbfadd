#include "programs.hpp"

#include "colour_ramp.hpp"
#include "gl_program.hpp"

namespace ultrasim::render::detail {
namespace {

constexpr const char* kColourVertex = R"(#version 300 es
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_colour;
uniform mat4 u_matrix;
out vec4 v_colour;
void main() {
  v_colour = a_colour;
  gl_Position = u_matrix * vec4(a_position, 1.0);
}
)";

constexpr const char* kColourFragment = R"(#version 300 es
precision mediump float;
in vec4 v_colour;
out vec4 o_colour;
void main() { o_colour = v_colour; }
)";

// The ramp arrives as a uniform array from colour_ramp.hpp, the table the legend also uses.
constexpr const char* kMeshVertex = R"(#version 300 es
layout(location = 0) in vec3 a_position_mm;
layout(location = 1) in float a_displacement_mm;
uniform mat4 u_view;
uniform mat4 u_projection;
uniform float u_inv_full_scale_per_mm;
uniform float u_fog_near_mm;
uniform float u_fog_far_mm;
uniform vec3 u_fog_colour;
uniform vec3 u_ramp[5];
out vec4 v_colour;
void main() {
  vec4 view_position = u_view * vec4(a_position_mm, 1.0);
  float x = clamp(a_displacement_mm * u_inv_full_scale_per_mm, 0.0, 1.0) * 4.0;
  int i = min(int(x), 3);
  vec3 colour = mix(u_ramp[i], u_ramp[i + 1], x - float(i));
  // Far lines fade towards the panel colour: a depth cue for a wireframe with no shading.
  float fade = clamp((-view_position.z - u_fog_near_mm) / (u_fog_far_mm - u_fog_near_mm), 0.0, 1.0);
  v_colour = vec4(mix(colour, u_fog_colour, 0.55 * fade), 1.0);
  gl_Position = u_projection * view_position;
}
)";

constexpr const char* kImageVertex = R"(#version 300 es
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec2 a_uv;
uniform mat4 u_matrix;
out vec2 v_uv;
void main() {
  v_uv = a_uv;
  gl_Position = u_matrix * vec4(a_position, 1.0);
}
)";

constexpr const char* kImageFragment = R"(#version 300 es
precision mediump float;
uniform sampler2D u_image;
uniform vec4 u_tint;
in vec2 v_uv;
out vec4 o_colour;
void main() {
  float grey = texture(u_image, v_uv).r;
  o_colour = vec4(vec3(grey), 1.0) * u_tint;
}
)";

// Surfaces. The view matrix is rigid (look_at), so its upper 3×3 turns normals as it turns
// directions. Lighting happens in view space, where the eye sits at the origin.
constexpr const char* kSurfaceVertex = R"(#version 300 es
layout(location = 0) in vec3 a_position_mm;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_view;
uniform mat4 u_projection;
out vec3 v_view_position_mm;
out vec3 v_view_normal;
void main() {
  vec4 view_position = u_view * vec4(a_position_mm, 1.0);
  v_view_position_mm = view_position.xyz;
  v_view_normal = mat3(u_view) * a_normal;
  gl_Position = u_projection * view_position;
}
)";

// highp: derivatives of positions some 100 mm from the eye need more than mediump's 10 bits.
// The face normal from derivatives always points at the viewer (window x right, y up); it is
// computed unconditionally so that derivatives stay in uniform control flow, and it stands in
// for a per-vertex normal of zero length (a degenerate spot of the caller's surface).
// gl_FrontFacing flips the interpolated normal on back faces: the far, inner wall of a
// translucent surface is lit from the side the viewer sees.
constexpr const char* kSurfaceFragment = R"(#version 300 es
precision highp float;
uniform vec4 u_colour;
uniform bool u_flat_shading;
in vec3 v_view_position_mm;
in vec3 v_view_normal;
out vec4 o_colour;
const float kAmbient = 0.28;
void main() {
  vec3 face_normal = normalize(cross(dFdx(v_view_position_mm), dFdy(v_view_position_mm)));
  vec3 normal = face_normal;
  float smooth_length2 = dot(v_view_normal, v_view_normal);
  if (!u_flat_shading && smooth_length2 > 1e-12) {
    normal = v_view_normal * inversesqrt(smooth_length2);
    if (!gl_FrontFacing) normal = -normal;
  }
  vec3 to_eye = normalize(-v_view_position_mm);
  float lambert = max(dot(normal, to_eye), 0.0);
  o_colour = vec4(u_colour.rgb * (kAmbient + (1.0 - kAmbient) * lambert), u_colour.a);
}
)";

}  // namespace

Programs build_programs() {
  Programs p;
  try {
    p.colour.id = build_program("colour", kColourVertex, kColourFragment);
    p.colour.u_matrix = uniform_location(p.colour.id, "colour", "u_matrix");

    p.mesh.id = build_program("mesh", kMeshVertex, kColourFragment);
    p.mesh.u_view = uniform_location(p.mesh.id, "mesh", "u_view");
    p.mesh.u_projection = uniform_location(p.mesh.id, "mesh", "u_projection");
    p.mesh.u_inv_full_scale_per_mm = uniform_location(p.mesh.id, "mesh", "u_inv_full_scale_per_mm");
    p.mesh.u_fog_near_mm = uniform_location(p.mesh.id, "mesh", "u_fog_near_mm");
    p.mesh.u_fog_far_mm = uniform_location(p.mesh.id, "mesh", "u_fog_far_mm");
    p.mesh.u_fog_colour = uniform_location(p.mesh.id, "mesh", "u_fog_colour");
    glUseProgram(p.mesh.id);
    glUniform3fv(uniform_location(p.mesh.id, "mesh", "u_ramp"), kRampStops, kRamp[0].data());

    p.image.id = build_program("image", kImageVertex, kImageFragment);
    p.image.u_matrix = uniform_location(p.image.id, "image", "u_matrix");
    p.image.u_tint = uniform_location(p.image.id, "image", "u_tint");
    glUseProgram(p.image.id);
    glUniform1i(uniform_location(p.image.id, "image", "u_image"), 0);

    p.surface.id = build_program("surface", kSurfaceVertex, kSurfaceFragment);
    p.surface.u_view = uniform_location(p.surface.id, "surface", "u_view");
    p.surface.u_projection = uniform_location(p.surface.id, "surface", "u_projection");
    p.surface.u_colour = uniform_location(p.surface.id, "surface", "u_colour");
    p.surface.u_flat_shading = uniform_location(p.surface.id, "surface", "u_flat_shading");
    glUseProgram(0);
  } catch (...) {
    destroy_programs(p);
    throw;
  }
  return p;
}

void destroy_programs(Programs& programs) {
  // glDeleteProgram ignores 0.
  glDeleteProgram(programs.colour.id);
  glDeleteProgram(programs.mesh.id);
  glDeleteProgram(programs.image.id);
  glDeleteProgram(programs.surface.id);
  programs = {};
}

}  // namespace ultrasim::render::detail
