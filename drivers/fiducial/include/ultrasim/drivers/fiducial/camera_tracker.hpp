#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>

#include "ultrasim/drivers/fiducial/body_pose.hpp"
#include "ultrasim/drivers/fiducial/pose_filter.hpp"
#include "ultrasim/drivers/fiducial/tag_detector.hpp"
#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/marker_model.hpp"

namespace ultrasim::drivers::fiducial {

struct CameraTrackerSettings {
  TagDetectorSettings detector;
  BodyPoseSettings pose;
  PoseFilterSettings filter;
  bool filtered = true;  // the 1€ filter on; off for measuring the raw pipeline
  hal::CameraIntrinsics camera;
  // Where the camera is in patient space, and where the probe's frame (hal::PoseSample's) is in
  // the marker body's frame; both rigid, mm.
  Eigen::Isometry3d patient_from_camera = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d body_from_probe = Eigen::Isometry3d::Identity();
  // While tracked, only the box around the body's last projection, grown by this margin, is
  // searched (the whole image when that finds nothing). 0: always the whole image.
  double search_margin_px = 40.0;
  // To find the body again, the whole image is searched coarsely first (AprilTag's usual
  // decimate 2, no upsampling: ~5 ms, and it misses the steep faces), then finely only around
  // the tags it found; the whole image finely (~30 ms) only when the coarse search finds none.
  bool coarse_acquisition = true;
  // A pose this far from the last one (a flip: a hand cannot turn the probe that fast between
  // two frames) is held back until it repeats `confirm_jump_frames` frames in a row; then it is
  // taken as a new track.
  double max_jump_deg = 30.0;
  double max_jump_mm = 40.0;
  int confirm_jump_frames = 3;
};

enum class TrackStatus : std::uint8_t {
  kTracked,
  kNoMarkers,     // none of the body's markers found
  kAmbiguous,     // one marker, two poses fit, nothing to choose by
  kInconsistent,  // the markers found agree on no pose
  kJumpHeld,      // a pose far from the last one, not yet confirmed
};

const char* to_string(TrackStatus status);

struct TrackResult {
  TrackStatus status = TrackStatus::kNoMarkers;
  // The probe's frame in patient space (filtered when the filter is on); set when tracked.
  std::optional<Eigen::Isometry3d> patient_from_probe;
  BodyPose body;  // the unfiltered fit, in camera space
  int tags_found = 0;
  bool searched_region = false;  // found within a box (no fine whole-image search)
};

struct TrackerCounters {
  std::uint64_t frames = 0;
  std::uint64_t tracked = 0;
  std::uint64_t no_markers = 0;
  std::uint64_t ambiguous = 0;
  std::uint64_t inconsistent = 0;
  std::uint64_t jumps_held = 0;
  std::uint64_t reacquired = 0;       // confirmed jumps: a new track taken
  std::uint64_t outlier_markers = 0;  // detections refused (far side, disagreeing corners)
  std::uint64_t region_searches = 0;
  std::uint64_t coarse_searches = 0;
  std::uint64_t whole_image_searches = 0;  // fine, over the whole image
};

// The camera tracking pipeline for one marker body: detect → fit → reject → filter, one frame at
// a time. Not thread-safe: it belongs to the tracking thread.
class CameraTracker {
 public:
  // Throws std::invalid_argument for bad detector settings or a body without markers.
  CameraTracker(hal::MarkerBody body, const CameraTrackerSettings& settings);

  // Tracks one frame. Allocates (detections).
  TrackResult track(const hal::CameraFrame& frame);

  const TrackerCounters& counters() const { return counters_; }
  const hal::MarkerBody& body() const { return body_; }
  const CameraTrackerSettings& settings() const { return settings_; }

 private:
  std::vector<TagDetection> detect(const hal::CameraFrame& frame, TrackResult& result);

  hal::MarkerBody body_;
  CameraTrackerSettings settings_;
  TagDetector detector_;
  TagDetector coarse_detector_;
  PoseFilter filter_;
  std::optional<Eigen::Isometry3d> last_camera_from_body_;  // last accepted (unfiltered)
  bool tracked_last_frame_ = false;
  int jump_frames_ = 0;
  int frames_since_tracked_ = 0;
  TrackerCounters counters_;
};

}  // namespace ultrasim::drivers::fiducial
