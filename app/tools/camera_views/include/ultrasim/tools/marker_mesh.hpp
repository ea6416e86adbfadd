#pragma once

// Camera views of the marker bodies (the dodecahedron, the published cube) drawn by our own
// renderer: the synthetic images the camera tracker is measured on, and recordings for the
// kiosk's camera-images source.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/marker_model.hpp"
#include "ultrasim/render/camera_view.hpp"
#include "ultrasim/render/rgba_image.hpp"

namespace ultrasim::tools {

// The body's faces (polygons, face i carrying marker i) textured with its tag36h11 tags as
// printed (white ring included, the black border as the body's markers say) on off-white card.
render::TexturedMesh marker_body_mesh(const hal::MarkerBody& body,
                                      const std::vector<std::vector<Eigen::Vector3d>>& faces,
                                      int tile_px = 256);

// A camera frame from a rendered view: its luminance blurred (Gaussian, sigma in px; 0 = none)
// and with Gaussian noise (sigma in grey levels), seeded, clipped to 0–255.
hal::CameraFrame camera_frame(const render::RgbaImage& view, double blur_sigma_px,
                              double noise_sigma, std::uint64_t seed);

}  // namespace ultrasim::tools
