#pragma once

// Minimal column-major 4×4 matrix and 3-vector maths for the renderer's camera and probe
// transforms (the layout OpenGL expects for glUniformMatrix4fv with transpose = GL_FALSE).
// Internal to render/.

#include <array>
#include <cmath>

namespace ultrasim::render::detail {

using Vec3 = std::array<float, 3>;
using Mat4 = std::array<float, 16>;  // element (row r, column c) at [c * 4 + r]

inline Vec3 operator+(const Vec3& a, const Vec3& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
inline Vec3 operator-(const Vec3& a, const Vec3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
inline Vec3 operator*(const Vec3& a, float s) {
  return {a[0] * s, a[1] * s, a[2] * s};
}
inline float dot(const Vec3& a, const Vec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline float length(const Vec3& a) {
  return std::sqrt(dot(a, a));
}
inline Vec3 normalized(const Vec3& a) {
  const float len = length(a);
  return len > 0.0f ? a * (1.0f / len) : Vec3{0.0f, 0.0f, 0.0f};
}

inline Mat4 identity() {
  return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
}

inline Mat4 multiply(const Mat4& a, const Mat4& b) {
  Mat4 m{};
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      float sum = 0.0f;
      for (int k = 0; k < 4; ++k) sum += a[k * 4 + r] * b[c * 4 + k];
      m[c * 4 + r] = sum;
    }
  }
  return m;
}

// Applies m to the point p (w = 1); the affine transforms used here need no perspective divide.
inline Vec3 transform_point(const Mat4& m, const Vec3& p) {
  return {m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
          m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
          m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14]};
}

// View matrix of a camera at eye looking at target with the given up direction.
inline Mat4 look_at(const Vec3& eye, const Vec3& target, const Vec3& up) {
  const Vec3 f = normalized(target - eye);
  const Vec3 s = normalized(cross(f, up));
  const Vec3 u = cross(s, f);
  return {s[0], u[0], -f[0], 0, s[1],         u[1],         -f[1],       0,
          s[2], u[2], -f[2], 0, -dot(s, eye), -dot(u, eye), dot(f, eye), 1};
}

inline Mat4 perspective(float fov_y_rad, float aspect, float near_z, float far_z) {
  const float f = 1.0f / std::tan(fov_y_rad * 0.5f);
  Mat4 m{};
  m[0] = f / aspect;
  m[5] = f;
  m[10] = (far_z + near_z) / (near_z - far_z);
  m[11] = -1.0f;
  m[14] = 2.0f * far_z * near_z / (near_z - far_z);
  return m;
}

// Maps screen pixels (origin top-left, y down) of a width × height target to clip space.
inline Mat4 pixel_ortho(float width, float height) {
  return {2.0f / width, 0, 0, 0, 0, -2.0f / height, 0, 0, 0, 0, -1, 0, -1, 1, 0, 1};
}

}  // namespace ultrasim::render::detail
