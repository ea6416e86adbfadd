#pragma once

// Synthetic camera views of the marker bodies (the dodecahedron, the cube), drawn by our own
// renderer: the ground truth the fiducial tracker is measured against.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/marker_model.hpp"
#include "ultrasim/render/camera_view.hpp"
#include "ultrasim/render/rgba_image.hpp"

namespace ultrasim::test {

// The body's faces (polygons, face i carrying marker i) textured with its tag36h11 tags as
// printed (white ring included, the black border as the body's markers say) on off-white card.
render::TexturedMesh marker_body_mesh(const hal::MarkerBody& body,
                                      const std::vector<std::vector<Eigen::Vector3d>>& faces,
                                      int tile_px = 256);

// A camera frame from a rendered view: its luminance blurred (Gaussian, sigma in px; 0 = none)
// and with Gaussian noise (sigma in grey levels), seeded, clipped to 0–255.
hal::CameraFrame camera_frame(const render::RgbaImage& view, double blur_sigma_px,
                              double noise_sigma, std::uint64_t seed);

// The 640 × 480 camera of the tests: 600 px focal length (a 56° horizontal field).
hal::CameraIntrinsics test_camera();

// A hand's sweep through every orientation: `frames` poses at 60 Hz (4 s for 240) turning the
// body once about a tilted axis and half a turn about the camera's axis while it circles in
// the image, 0.3–0.4 m away: about 90°/s and 150 mm/s.
std::vector<Eigen::Isometry3d> sweep_poses(int frames);

}  // namespace ultrasim::test
