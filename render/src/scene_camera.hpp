#pragma once

// Where the 3D view's camera stands. Internal to render/.

#include <array>

#include "mat4.hpp"
#include "ultrasim/render/scene_style.hpp"

namespace ultrasim::render::detail {

struct SceneCamera {
  Mat4 view = identity();
  Mat4 projection = identity();
  Vec3 eye_mm{};
  float target_distance_mm = 1.0f;  // eye to the centre of the framed box
  float framed_radius_mm = 1.0f;    // radius of the sphere that fits the view
};

// A perspective camera that frames the box [min_mm, max_mm] (grown upwards, -z, by headroom_mm
// so the probe above the skin stays in view) from the style's azimuth and elevation, with
// patient -z (towards the skin) up on screen. A box that is empty, inverted or not finite is
// replaced by a 100 mm cube under the origin. aspect = viewport width / height. zoom > 1 moves
// the camera closer to the framed centre (clamped to 0.25..8; not finite: 1). Pure.
SceneCamera frame_scene(const std::array<float, 3>& min_mm, const std::array<float, 3>& max_mm,
                        float headroom_mm, const SceneStyle& style, float aspect,
                        float zoom = 1.0f);

}  // namespace ultrasim::render::detail
