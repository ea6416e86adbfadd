#include "ultrasim/drivers/fiducial/camera_tracker.hpp"

#include <stdexcept>

namespace ultrasim::drivers::fiducial {

const char* to_string(TrackStatus status) {
  switch (status) {
    case TrackStatus::kTracked:
      return "tracked";
    case TrackStatus::kNoMarkers:
      return "no markers";
    case TrackStatus::kAmbiguous:
      return "ambiguous";
    case TrackStatus::kInconsistent:
      return "inconsistent markers";
    case TrackStatus::kJumpHeld:
      return "jump held";
  }
  return "?";
}

CameraTracker::CameraTracker(hal::MarkerBody body, const CameraTrackerSettings& settings)
    : body_(std::move(body)),
      settings_(settings),
      detector_(settings.detector),
      filter_(settings.filter) {
  if (body_.markers.empty()) throw std::invalid_argument("camera tracker: the body has no markers");
  if (body_.family != settings.detector.family) {
    throw std::invalid_argument("camera tracker: the body's markers are " + body_.family +
                                " but the detector looks for " + settings.detector.family);
  }
  const auto& c = settings.camera;
  if (!(c.fx_px > 0.0) || !(c.fy_px > 0.0)) {
    throw std::invalid_argument("camera tracker: camera focal lengths must be > 0 px");
  }
}

std::vector<TagDetection> CameraTracker::detect(const hal::CameraFrame& frame,
                                                TrackResult& result) {
  if (tracked_last_frame_ && last_camera_from_body_ && settings_.search_margin_px > 0.0) {
    ++counters_.region_searches;
    const PixelRegion region = projected_region(body_, settings_.camera, *last_camera_from_body_,
                                                settings_.search_margin_px);
    auto found = detector_.detect(frame, region);
    if (!found.empty()) {
      result.searched_region = true;
      return found;
    }
  }
  ++counters_.whole_image_searches;
  return detector_.detect(frame);
}

TrackResult CameraTracker::track(const hal::CameraFrame& frame) {
  ++counters_.frames;
  TrackResult result;
  const auto detections = detect(frame, result);
  result.tags_found = static_cast<int>(detections.size());
  result.body = estimate_body_pose(body_, settings_.camera, detections,
                                   tracked_last_frame_ ? last_camera_from_body_ : std::nullopt,
                                   settings_.pose);
  counters_.outlier_markers += result.body.outlier_ids.size();
  switch (result.body.status) {
    case BodyPoseStatus::kOk:
      break;
    case BodyPoseStatus::kNoMarkers:
      result.status = TrackStatus::kNoMarkers;
      ++counters_.no_markers;
      break;
    case BodyPoseStatus::kAmbiguous:
      result.status = TrackStatus::kAmbiguous;
      ++counters_.ambiguous;
      break;
    case BodyPoseStatus::kInconsistent:
      result.status = TrackStatus::kInconsistent;
      ++counters_.inconsistent;
      break;
  }
  if (result.body.status != BodyPoseStatus::kOk) {
    tracked_last_frame_ = false;
    ++frames_since_tracked_;
    jump_frames_ = 0;
    return result;
  }
  const Eigen::Isometry3d& pose = result.body.camera_from_body;
  // After a long loss the body may be anywhere: no jump to judge against.
  if (last_camera_from_body_ && frames_since_tracked_ <= settings_.confirm_jump_frames) {
    const double turned_deg =
        Eigen::AngleAxisd(last_camera_from_body_->linear().transpose() * pose.linear()).angle() *
        180.0 / 3.14159265358979323846;
    const double moved_mm = (pose.translation() - last_camera_from_body_->translation()).norm();
    if (turned_deg > settings_.max_jump_deg || moved_mm > settings_.max_jump_mm) {
      if (++jump_frames_ < settings_.confirm_jump_frames) {
        result.status = TrackStatus::kJumpHeld;
        ++counters_.jumps_held;
        ++frames_since_tracked_;
        return result;
      }
      ++counters_.reacquired;
      filter_.reset();
    }
  }
  jump_frames_ = 0;
  frames_since_tracked_ = 0;
  last_camera_from_body_ = pose;
  tracked_last_frame_ = true;
  const Eigen::Isometry3d smoothed =
      settings_.filtered ? filter_.update(pose, frame.timestamp_us) : pose;
  result.patient_from_probe = settings_.patient_from_camera * smoothed * settings_.body_from_probe;
  result.status = TrackStatus::kTracked;
  ++counters_.tracked;
  return result;
}

}  // namespace ultrasim::drivers::fiducial
