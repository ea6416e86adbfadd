#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"

namespace ultrasim::render {

// A rigid body's surface with a grey texture (faces with markers printed on them), in the body's
// frame, mm. Flat faces repeat their vertices so each carries its face's normal.
struct TexturedMesh {
  std::vector<Eigen::Vector3f> positions_mm;
  std::vector<Eigen::Vector3f> normals;    // unit, outward, one per position
  std::vector<Eigen::Vector2f> texcoords;  // [0, 1]², (0, 0) the texture's first pixel
  std::vector<std::uint32_t> triangles;    // three indices each, counter-clockwise seen outside
  int texture_width_px = 0;
  int texture_height_px = 0;
  std::vector<std::uint8_t> texture_grey;  // row-major, first row first
};

// The light of one view: a directional light (camera frame, pointing from the light toward the
// scene) and ambient; grey levels come out as texture × (ambient + diffuse × cos θ).
struct ViewLighting {
  Eigen::Vector3d direction_camera = Eigen::Vector3d(0.3, 0.4, 1.0);
  double ambient = 0.35;
  double diffuse = 0.75;
  std::uint8_t background_grey = 90;
};

// Draws a TexturedMesh as a pinhole camera (hal::CameraIntrinsics, no lens distortion) would see
// it: the synthetic camera images the fiducial tracker is measured on. Pixel (u, v) of the
// framebuffer, read back rows top first, is the camera's pixel (u, v). Every member must be
// called on the render thread, with the Display's context current.
class CameraViewRenderer {
 public:
  // Uploads the mesh and its texture (mipmapped). Throws std::invalid_argument for a mesh whose
  // arrays disagree in size or index out of range, std::runtime_error for a GL failure.
  explicit CameraViewRenderer(const TexturedMesh& mesh);
  ~CameraViewRenderer();
  CameraViewRenderer(const CameraViewRenderer&) = delete;
  CameraViewRenderer& operator=(const CameraViewRenderer&) = delete;

  // Clears the bound framebuffer (width_px × height_px, the camera's image size) to the
  // background and draws the body at camera_from_body (mm; camera x right, y down, z forward).
  void draw(const hal::CameraIntrinsics& camera, int width_px, int height_px,
            const Eigen::Isometry3d& camera_from_body, const ViewLighting& lighting);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ultrasim::render
