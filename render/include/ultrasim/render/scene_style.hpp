#pragma once

namespace ultrasim::render {

// How the kiosk screen looks; fixed for a SceneRenderer's lifetime. Defaults are the kiosk's.
struct SceneStyle {
  // Share of the screen width given to the 3D view; the B-scan panel takes the rest.
  float view_fraction = 0.55f;
  // Displacement magnitude drawn fully red; 0 mm is blue. A fixed scale (not the frame's maximum)
  // so that the same colour means the same compression from frame to frame.
  float displacement_full_scale_mm = 5.0f;
  // Camera around the centre of the scene: azimuth turns from straight-on (+y side, looking
  // along -y, so +x runs to the right as in the B-scan) towards +x; elevation lifts it above the
  // skin (-z). Vertical field of view of the perspective projection.
  float camera_azimuth_deg = 28.0f;
  float camera_elevation_deg = 32.0f;
  float camera_fov_y_deg = 32.0f;
  // Thin grey box around the scene bounds.
  bool show_scene_bounds = true;
};

}  // namespace ultrasim::render
