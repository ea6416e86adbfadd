#pragma once

// Closed triangle surfaces for render tests, the screenshot demo and its timing: boxes and tubes
// (round or squashed along their length, as a vein under a probe), counter-clockwise outside,
// with per-vertex normals. Deterministic. A SyntheticSurface's view() points into its vectors:
// keep the surface alive and unmoved-from while the view is in use.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numbers>
#include <span>
#include <vector>

#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::render::testing {

// The colours the kiosk sends (app/kiosk display_surfaces.cpp).
inline constexpr std::array<float, 4> kVeinRgba{0.25f, 0.45f, 0.95f, 1.0f};
inline constexpr std::array<float, 4> kArteryRgba{0.90f, 0.20f, 0.20f, 1.0f};
inline constexpr std::array<float, 4> kNerveRgba{0.95f, 0.85f, 0.30f, 1.0f};
inline constexpr std::array<float, 4> kBoneRgba{0.92f, 0.90f, 0.80f, 1.0f};

struct SyntheticSurface {
  std::vector<float> positions_mm;
  std::vector<float> normals;
  std::vector<std::uint32_t> triangles;

  std::size_t vertex_count() const { return positions_mm.size() / 3; }
  std::size_t triangle_count() const { return triangles.size() / 3; }

  // with_normals = false: an empty normals span, so the renderer shades flat.
  SurfaceView view(const std::array<float, 4>& rgba, bool with_normals = true) const {
    SurfaceView v;
    v.positions_mm = positions_mm;
    if (with_normals) v.normals = normals;
    v.triangles = triangles;
    v.rgba = rgba;
    return v;
  }

  std::array<float, 3> vertex(std::uint32_t i) const {
    return {positions_mm[3 * i], positions_mm[3 * i + 1], positions_mm[3 * i + 2]};
  }

  std::uint32_t add_vertex(const std::array<float, 3>& p) {
    positions_mm.insert(positions_mm.end(), p.begin(), p.end());
    return static_cast<std::uint32_t>(vertex_count() - 1);
  }

  // Area-weighted vertex normals from the faces (what the kiosk computes for deformed surfaces).
  void compute_normals() {
    normals.assign(positions_mm.size(), 0.0f);
    for (std::size_t t = 0; t < triangle_count(); ++t) {
      const std::uint32_t i[3] = {triangles[3 * t], triangles[3 * t + 1], triangles[3 * t + 2]};
      const auto a = vertex(i[0]);
      const auto b = vertex(i[1]);
      const auto c = vertex(i[2]);
      const float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                          e1[0] * e2[1] - e1[1] * e2[0]};
      for (const std::uint32_t v : i) {
        for (int k = 0; k < 3; ++k) normals[3 * v + k] += n[k];
      }
    }
    for (std::size_t v = 0; v < vertex_count(); ++v) {
      float* n = &normals[3 * v];
      const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (len > 0.0f) {
        for (int k = 0; k < 3; ++k) n[k] /= len;
      }
    }
  }

  // Six times the signed volume: positive when the triangles wind counter-clockwise seen from
  // outside a closed surface.
  double signed_volume_x6() const {
    double sum = 0.0;
    for (std::size_t t = 0; t < triangle_count(); ++t) {
      const auto a = vertex(triangles[3 * t]);
      const auto b = vertex(triangles[3 * t + 1]);
      const auto c = vertex(triangles[3 * t + 2]);
      sum += static_cast<double>(a[0]) * (b[1] * c[2] - b[2] * c[1]) -
             static_cast<double>(a[1]) * (b[0] * c[2] - b[2] * c[0]) +
             static_cast<double>(a[2]) * (b[0] * c[1] - b[1] * c[0]);
    }
    return sum;
  }
};

// An axis-aligned box, four vertices per face so each face has its own normal.
inline SyntheticSurface make_box(const std::array<float, 3>& lo_mm,
                                 const std::array<float, 3>& hi_mm) {
  SyntheticSurface s;
  const auto corner = [&](int i) {
    return std::array<float, 3>{(i & 1) ? hi_mm[0] : lo_mm[0], (i & 2) ? hi_mm[1] : lo_mm[1],
                                (i & 4) ? hi_mm[2] : lo_mm[2]};
  };
  // Corner bits (x = 1, y = 2, z = 4) of each face, counter-clockwise seen from outside.
  constexpr int kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& face : kFaces) {
    const std::uint32_t first = static_cast<std::uint32_t>(s.vertex_count());
    for (const int c : face) s.add_vertex(corner(c));
    s.triangles.insert(s.triangles.end(),
                       {first, first + 1, first + 2, first, first + 2, first + 3});
  }
  s.compute_normals();
  return s;
}

// A closed tube along +y from y0_mm to y1_mm. At each y the cross-section is an ellipse with
// half-axes half_x(y) and half_z(y) around (centre_x, centre_z(y)); segments_around points per
// ring, rings_along + 1 rings. Flat caps with their own vertices (so their normals stay ±y).
// Triangles: 2 × segments_around × rings_along + 2 × segments_around.
struct TubeShape {
  float y0_mm = 0.0f;
  float y1_mm = 40.0f;
  std::function<float(float)> centre_x_mm;
  std::function<float(float)> centre_z_mm;
  std::function<float(float)> half_x_mm;
  std::function<float(float)> half_z_mm;
};

inline SyntheticSurface make_tube(const TubeShape& shape, int segments_around, int rings_along) {
  SyntheticSurface s;
  const int n = std::max(segments_around, 3);
  const int rings = std::max(rings_along, 1);
  const auto ring_point = [&](int i, float y) {
    const float angle = 2.0f * std::numbers::pi_v<float> * static_cast<float>(i) / n;
    return std::array<float, 3>{shape.centre_x_mm(y) + shape.half_x_mm(y) * std::cos(angle), y,
                                shape.centre_z_mm(y) + shape.half_z_mm(y) * std::sin(angle)};
  };
  // The last ring exactly at y1, so that the far cap meets it bit for bit.
  const auto y_of = [&](int j) {
    if (j == rings) return shape.y1_mm;
    return shape.y0_mm + (shape.y1_mm - shape.y0_mm) * static_cast<float>(j) / rings;
  };
  for (int j = 0; j <= rings; ++j) {
    for (int i = 0; i < n; ++i) s.add_vertex(ring_point(i, y_of(j)));
  }
  const auto wall = [n](int i, int j) { return static_cast<std::uint32_t>(j * n + (i % n)); };
  for (int j = 0; j < rings; ++j) {
    for (int i = 0; i < n; ++i) {
      // Around (+angle) crossed with along (+y) points inwards: list along before around.
      s.triangles.insert(s.triangles.end(), {wall(i, j), wall(i, j + 1), wall(i + 1, j)});
      s.triangles.insert(s.triangles.end(), {wall(i + 1, j), wall(i, j + 1), wall(i + 1, j + 1)});
    }
  }
  for (const bool far_end : {false, true}) {
    const float y = far_end ? shape.y1_mm : shape.y0_mm;
    const std::uint32_t centre = s.add_vertex({shape.centre_x_mm(y), y, shape.centre_z_mm(y)});
    const std::uint32_t first = static_cast<std::uint32_t>(s.vertex_count());
    for (int i = 0; i < n; ++i) s.add_vertex(ring_point(i, y));
    for (int i = 0; i < n; ++i) {
      const std::uint32_t a = first + static_cast<std::uint32_t>(i);
      const std::uint32_t b = first + static_cast<std::uint32_t>((i + 1) % n);
      // The near cap faces -y, the far cap +y.
      if (far_end) {
        s.triangles.insert(s.triangles.end(), {centre, b, a});
      } else {
        s.triangles.insert(s.triangles.end(), {centre, a, b});
      }
    }
  }
  s.compute_normals();
  return s;
}

// segments_around × rings_along for a tube of about `triangles` triangles (as many rings as
// segments).
inline std::array<int, 2> tube_resolution(int triangles) {
  const int t = std::max(triangles, 48);
  const int around = std::max(8, static_cast<int>(std::lround(std::sqrt(0.5f * t))));
  const int along = std::max(1, (t - 2 * around) / (2 * around));
  return {around, along};
}

}  // namespace ultrasim::render::testing
