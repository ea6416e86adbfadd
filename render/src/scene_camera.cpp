#include "scene_camera.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace ultrasim::render::detail {

SceneCamera frame_scene(const std::array<float, 3>& min_mm, const std::array<float, 3>& max_mm,
                        float headroom_mm, const SceneStyle& style, float aspect) {
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
  // The sphere must fit the narrower of the two fields of view.
  const float half_fov_x = std::atan(std::tan(fov_y * 0.5f) * safe_aspect);
  const float half_fov = std::min(fov_y * 0.5f, half_fov_x);
  const float distance = radius / std::sin(half_fov) * 1.02f;

  SceneCamera camera;
  camera.eye_mm = centre + to_eye * distance;
  camera.view = look_at(camera.eye_mm, centre, {0.0f, 0.0f, -1.0f});
  // Near and far leave room for a probe that rises out of the framed sphere.
  const float near_mm = std::max(distance - 3.0f * radius, distance * 0.05f);
  const float far_mm = distance + 3.0f * radius;
  camera.projection = perspective(fov_y, safe_aspect, near_mm, far_mm);
  camera.target_distance_mm = distance;
  camera.framed_radius_mm = radius;
  return camera;
}

}  // namespace ultrasim::render::detail
