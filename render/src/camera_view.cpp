#include "ultrasim/render/camera_view.hpp"

#include <GLES3/gl3.h>

#include <array>
#include <cstring>
#include <stdexcept>
#include <string>

#include "gl_program.hpp"

namespace ultrasim::render {

namespace {

const char* const kVertexSource = R"(#version 300 es
uniform mat4 u_clip_from_body;
uniform mat3 u_camera_from_body;
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_texcoord;
out vec3 v_normal;
out vec2 v_texcoord;
void main() {
  v_normal = u_camera_from_body * a_normal;
  v_texcoord = a_texcoord;
  gl_Position = u_clip_from_body * vec4(a_position, 1.0);
}
)";

const char* const kFragmentSource = R"(#version 300 es
precision mediump float;
uniform sampler2D u_texture;
uniform vec3 u_light_camera;
uniform float u_ambient;
uniform float u_diffuse;
in vec3 v_normal;
in vec2 v_texcoord;
out vec4 o_colour;
void main() {
  float lambert = max(dot(normalize(v_normal), -u_light_camera), 0.0);
  float grey = texture(u_texture, v_texcoord).r * (u_ambient + u_diffuse * lambert);
  o_colour = vec4(vec3(min(grey, 1.0)), 1.0);
}
)";

// The clip transform of a pinhole camera with OpenCV's pixel convention: pixel (u, v) is the
// window's pixel centre (u + 0.5, height − v − 0.5). Column-major, for glUniformMatrix4fv.
std::array<float, 16> clip_from_camera(const hal::CameraIntrinsics& c, int width, int height,
                                       double near_mm, double far_mm) {
  const double w = width, h = height;
  std::array<float, 16> m{};
  const auto at = [&m](int row, int col) -> float& { return m[col * 4 + row]; };
  at(0, 0) = static_cast<float>(2.0 * c.fx_px / w);
  at(0, 2) = static_cast<float>(2.0 * (c.cx_px + 0.5) / w - 1.0);
  at(1, 1) = static_cast<float>(-2.0 * c.fy_px / h);
  at(1, 2) = static_cast<float>(1.0 - 2.0 * (c.cy_px + 0.5) / h);
  at(2, 2) = static_cast<float>((far_mm + near_mm) / (far_mm - near_mm));
  at(2, 3) = static_cast<float>(-2.0 * far_mm * near_mm / (far_mm - near_mm));
  at(3, 2) = 1.0f;
  return m;
}

}  // namespace

struct CameraViewRenderer::Impl {
  GLuint program = 0;
  GLint u_clip_from_body = -1, u_camera_from_body = -1, u_texture = -1, u_light = -1,
        u_ambient = -1, u_diffuse = -1;
  GLuint vao = 0, vertices = 0, indices = 0, texture = 0;
  GLsizei index_count = 0;
};

CameraViewRenderer::CameraViewRenderer(const TexturedMesh& mesh) : impl_(std::make_unique<Impl>()) {
  const std::size_t n = mesh.positions_mm.size();
  if (mesh.normals.size() != n || mesh.texcoords.size() != n || mesh.triangles.size() % 3 != 0 ||
      mesh.texture_width_px <= 0 || mesh.texture_height_px <= 0 ||
      mesh.texture_grey.size() !=
          static_cast<std::size_t>(mesh.texture_width_px) * mesh.texture_height_px) {
    throw std::invalid_argument(
        "camera view: positions, normals and texcoords must match, triangles come in threes, "
        "and the texture must hold width x height pixels");
  }
  for (std::uint32_t i : mesh.triangles) {
    if (i >= n) throw std::invalid_argument("camera view: triangle index out of range");
  }
  auto& g = *impl_;
  g.program = detail::build_program("camera view", kVertexSource, kFragmentSource);
  g.u_clip_from_body = detail::uniform_location(g.program, "camera view", "u_clip_from_body");
  g.u_camera_from_body = detail::uniform_location(g.program, "camera view", "u_camera_from_body");
  g.u_texture = detail::uniform_location(g.program, "camera view", "u_texture");
  g.u_light = detail::uniform_location(g.program, "camera view", "u_light_camera");
  g.u_ambient = detail::uniform_location(g.program, "camera view", "u_ambient");
  g.u_diffuse = detail::uniform_location(g.program, "camera view", "u_diffuse");

  std::vector<float> interleaved;
  interleaved.reserve(n * 8);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) interleaved.push_back(mesh.positions_mm[i][k]);
    for (int k = 0; k < 3; ++k) interleaved.push_back(mesh.normals[i][k]);
    for (int k = 0; k < 2; ++k) interleaved.push_back(mesh.texcoords[i][k]);
  }
  glGenVertexArrays(1, &g.vao);
  glBindVertexArray(g.vao);
  glGenBuffers(1, &g.vertices);
  glBindBuffer(GL_ARRAY_BUFFER, g.vertices);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(interleaved.size() * sizeof(float)),
               interleaved.data(), GL_STATIC_DRAW);
  const GLsizei stride = 8 * sizeof(float);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride,
                        reinterpret_cast<const void*>(3 * sizeof(float)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 2, GL_FLOAT, GL_FALSE, stride,
                        reinterpret_cast<const void*>(6 * sizeof(float)));
  glGenBuffers(1, &g.indices);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.indices);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER,
               static_cast<GLsizeiptr>(mesh.triangles.size() * sizeof(std::uint32_t)),
               mesh.triangles.data(), GL_STATIC_DRAW);
  g.index_count = static_cast<GLsizei>(mesh.triangles.size());
  glBindVertexArray(0);

  glGenTextures(1, &g.texture);
  glBindTexture(GL_TEXTURE_2D, g.texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, mesh.texture_width_px, mesh.texture_height_px, 0, GL_RED,
               GL_UNSIGNED_BYTE, mesh.texture_grey.data());
  // Trilinear: a tag far off blurs the way a lens and sensor blur it, instead of aliasing into
  // patterns no camera makes. Anisotropic where the driver has it (llvmpipe does): isotropic
  // mipmaps blur a face seen at a grazing angle along both axes, far more than a camera does.
  glGenerateMipmap(GL_TEXTURE_2D);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  const char* extensions = reinterpret_cast<const char*>(glGetString(GL_EXTENSIONS));
  if (extensions && std::strstr(extensions, "GL_EXT_texture_filter_anisotropic")) {
    constexpr GLenum kMaxAnisotropy = 0x84FE;  // GL_TEXTURE_MAX_ANISOTROPY_EXT
    glTexParameterf(GL_TEXTURE_2D, kMaxAnisotropy, 16.0f);
  }
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  if (glGetError() != GL_NO_ERROR) throw std::runtime_error("camera view: GL upload failed");
}

CameraViewRenderer::~CameraViewRenderer() {
  auto& g = *impl_;
  glDeleteTextures(1, &g.texture);
  glDeleteBuffers(1, &g.indices);
  glDeleteBuffers(1, &g.vertices);
  glDeleteVertexArrays(1, &g.vao);
  glDeleteProgram(g.program);
}

void CameraViewRenderer::draw(const hal::CameraIntrinsics& camera, int width_px, int height_px,
                              const Eigen::Isometry3d& camera_from_body,
                              const ViewLighting& lighting) {
  auto& g = *impl_;
  const float bg = lighting.background_grey / 255.0f;
  glViewport(0, 0, width_px, height_px);
  glClearColor(bg, bg, bg, 1.0f);
  glClearDepthf(1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDisable(GL_BLEND);
  // The camera looks along +z and its image's y points down, which mirrors the window: the
  // winding seen on screen flips, so cull nothing rather than reason about it.
  glDisable(GL_CULL_FACE);

  const auto projection = clip_from_camera(camera, width_px, height_px, 10.0, 5000.0);
  const Eigen::Matrix4f body = camera_from_body.matrix().cast<float>();
  Eigen::Matrix4f clip;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) clip(r, c) = projection[static_cast<std::size_t>(c * 4 + r)];
  const Eigen::Matrix4f clip_from_body = clip * body;
  const Eigen::Matrix3f rotation = camera_from_body.linear().cast<float>();
  const Eigen::Vector3f light = lighting.direction_camera.normalized().cast<float>();

  glUseProgram(g.program);
  glUniformMatrix4fv(g.u_clip_from_body, 1, GL_FALSE, clip_from_body.data());
  glUniformMatrix3fv(g.u_camera_from_body, 1, GL_FALSE, rotation.data());
  glUniform3f(g.u_light, light.x(), light.y(), light.z());
  glUniform1f(g.u_ambient, static_cast<float>(lighting.ambient));
  glUniform1f(g.u_diffuse, static_cast<float>(lighting.diffuse));
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, g.texture);
  glUniform1i(g.u_texture, 0);
  glBindVertexArray(g.vao);
  glDrawElements(GL_TRIANGLES, g.index_count, GL_UNSIGNED_INT, nullptr);
  glBindVertexArray(0);
}

}  // namespace ultrasim::render
