#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <span>
#include <vector>

#include "ultrasim/drivers/fiducial/tag_detector.hpp"
#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/marker_model.hpp"

namespace ultrasim::drivers::fiducial {

struct BodyPoseSettings {
  // A marker agrees with a pose when each of its corners reprojects within this many pixels.
  double max_corner_error_px = 4.0;
  // A marker can be seen only when the angle between its outward normal and the direction to the
  // camera is below arccos(this): a detection on a face turned away (the far side of the body,
  // whose faces cannot be seen together with the near side) is an outlier.
  double min_facing_cosine = 0.05;
  // A pose resting on one marker alone is ambiguous (a square seen face-on fits two poses) unless
  // the second of its two planar solutions reprojects at least this many times worse.
  double ambiguity_ratio = 4.0;
};

enum class BodyPoseStatus : std::uint8_t {
  kOk,
  kNoMarkers,     // no detection of the body's markers
  kAmbiguous,     // one marker, two poses fit it alike, and no earlier pose to choose by
  kInconsistent,  // the detections agree on no pose
};

// The body's pose from every visible marker's corners at once.
struct BodyPose {
  BodyPoseStatus status = BodyPoseStatus::kNoMarkers;
  Eigen::Isometry3d camera_from_body = Eigen::Isometry3d::Identity();  // mm
  std::vector<int> inlier_ids;                                         // markers the pose rests on
  std::vector<int> outlier_ids;  // detected but refused: far side, or corners that disagree
  double rms_error_px = 0.0;     // over the inliers' corners
  bool ambiguous = false;        // one marker only; the solution nearer `prior` was taken
};

// Fits the body's pose to `detections` (unknown ids ignored): every single-marker planar
// solution (two per marker) and `prior` are tried as hypotheses; the one most markers agree with
// (facing the camera, corners within tolerance) is refined by Levenberg–Marquardt over all those
// markers' corners, and the markers are re-checked against the refined pose. Allocates.
BodyPose estimate_body_pose(const hal::MarkerBody& body, const hal::CameraIntrinsics& camera,
                            std::span<const TagDetection> detections,
                            const std::optional<Eigen::Isometry3d>& prior,
                            const BodyPoseSettings& settings = {});

// The pixel box around the body's markers seen at `camera_from_body`, grown by margin_px on
// each side (not clipped to the image).
PixelRegion projected_region(const hal::MarkerBody& body, const hal::CameraIntrinsics& camera,
                             const Eigen::Isometry3d& camera_from_body, double margin_px);

}  // namespace ultrasim::drivers::fiducial
