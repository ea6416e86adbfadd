#include "scene_camera.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace ultrasim::render::detail {

SceneCamera frame_scene(const std::array<float, 3>& min_mm, const std::array<float, 3>& max_mm,
                        float headroom_mm, const SceneStyle& style, float aspect, float zoom) {
  Vec3 lo{min_mm[0], min_mm[1], min_mm[2]};
  Vec3 hi{max_mm[0], max_mm[1], max_mm[2]};
  bool valid = true;
  for (int k = 0; k < 3; ++k) {
    valid = valid && std::isfinite(lo[k]) && std::isfinite(hi[k]) && hi[k] > lo[k];
  }
  if (!valid) {
    lo = {-50.0f, -50.0f, 0.0f};
    hi = {50.0f, 50.0f, 100.0f};
  }
  if (std::isfinite(headroom_mm) && headroom_mm > 0.0f) lo[2] -= headroom_mm;

  const Vec3 centre = (lo + hi) * 0.5f;
  const float radius = std::max(length(hi - lo) * 0.5f, 1e-3f);
  constexpr float kDegToRad = std::numbers::pi_v<float> / 180.0f;
  const float azimuth = style.camera_azimuth_deg * kDegToRad;
  const float elevation = std::clamp(style.camera_elevation_deg, -85.0f, 85.0f) * kDegToRad;
  const float fov_y = std::clamp(style.camera_fov_y_deg, 5.0f, 120.0f) * kDegToRad;
  const float safe_aspect = std::isfinite(aspect) && aspect > 0.0f ? aspect : 1.0f;

  // Straight-on is from +y looking along -y: with -z up, +x then runs to the right, as the
  // B-scan's lateral axis does in the panel beside it.
  const Vec3 to_eye{std::sin(azimuth) * std::cos(elevation),
                    std::cos(azimuth) * std::cos(elevation), -std::sin(elevation)};
  // Fit the box's eight corners, not its bounding sphere (which wastes a third of the panel):
  // for each corner, the distance at which it just touches the edge of the view.
  const float tan_half_y = std::tan(fov_y * 0.5f);
  const float tan_half_x = tan_half_y * safe_aspect;
  const Vec3 up{0.0f, 0.0f, -1.0f};
  const Vec3 right = normalized(cross(to_eye * -1.0f, up));
  const Vec3 cam_up = cross(right, to_eye * -1.0f);
  const auto corner = [&](int i) {
    return Vec3{(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]};
  };
  const auto fit_distance = [&](const Vec3& target) {
    float needed = 0.0f;
    for (int i = 0; i < 8; ++i) {
      const Vec3 rel = corner(i) - target;
      const float toward_eye = dot(rel, to_eye);
      needed = std::max(needed, toward_eye + std::abs(dot(rel, right)) / tan_half_x);
      needed = std::max(needed, toward_eye + std::abs(dot(rel, cam_up)) / tan_half_y);
    }
    return needed;
  };
  // Perspective makes the near side look bigger, so the box's image is off-centre: shift the
  // target by the centre of the projected extents once, then fit again.
  Vec3 target = centre;
  float distance = fit_distance(target);
  float min_x = 1e30f, max_x = -1e30f, min_y = 1e30f, max_y = -1e30f;
  for (int i = 0; i < 8; ++i) {
    const Vec3 rel = corner(i) - target;
    const float depth = std::max(distance - dot(rel, to_eye), 1e-3f);
    min_x = std::min(min_x, dot(rel, right) / depth);
    max_x = std::max(max_x, dot(rel, right) / depth);
    min_y = std::min(min_y, dot(rel, cam_up) / depth);
    max_y = std::max(max_y, dot(rel, cam_up) / depth);
  }
  target = target + right * (0.5f * (min_x + max_x) * distance) +
           cam_up * (0.5f * (min_y + max_y) * distance);
  // 6 % breathing room around the scene.
  distance =
      fit_distance(target) * 1.06f / (std::isfinite(zoom) ? std::clamp(zoom, 0.25f, 8.0f) : 1.0f);

  SceneCamera camera;
  camera.eye_mm = target + to_eye * distance;
  camera.view = look_at(camera.eye_mm, target, up);
  // Near and far leave room for a probe that rises out of the framed box.
  const float near_mm = std::max(distance - 3.0f * radius, distance * 0.05f);
  const float far_mm = distance + 3.0f * radius;
  camera.projection = perspective(fov_y, safe_aspect, near_mm, far_mm);
  camera.target_distance_mm = distance;
  camera.framed_radius_mm = radius;
  return camera;
}

}  // namespace ultrasim::render::detail
