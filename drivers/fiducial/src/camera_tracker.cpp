#include "ultrasim/drivers/fiducial/camera_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ultrasim::drivers::fiducial {

const char* to_string(TrackStatus status) {
  switch (status) {
    case TrackStatus::kTracked:
      return "tracked";
    case TrackStatus::kNoMarkers:
      return "no markers in view";
    case TrackStatus::kAmbiguous:
      return "one marker only, ambiguous";
    case TrackStatus::kInconsistent:
      return "markers disagree";
    case TrackStatus::kJumpHeld:
      return "sudden jump held back";
  }
  return "?";
}

namespace {

TagDetectorSettings coarse(TagDetectorSettings fine) {
  fine.quad_decimate = 2.0;
  fine.upsample = 1.0;
  fine.equalise_clip_limit = 0.0;
  return fine;
}

// The box around a set of detections, grown by their own size and `margin_px` on each side: the
// body's other faces lie within about one tag's size of those found.
PixelRegion around(const std::vector<TagDetection>& found, double margin_px) {
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& d : found) {
    for (const auto& c : d.corners_px) {
      x0 = std::min(x0, c.x());
      y0 = std::min(y0, c.y());
      x1 = std::max(x1, c.x());
      y1 = std::max(y1, c.y());
    }
  }
  const double grow = std::max(x1 - x0, y1 - y0) + margin_px;
  const int left = static_cast<int>(std::floor(x0 - grow));
  const int top = static_cast<int>(std::floor(y0 - grow));
  return {left, top, static_cast<int>(std::ceil(x1 + grow)) - left + 1,
          static_cast<int>(std::ceil(y1 + grow)) - top + 1};
}

}  // namespace

CameraTracker::CameraTracker(hal::MarkerBody body, const CameraTrackerSettings& settings)
    : body_(std::move(body)),
      settings_(settings),
      detector_(settings.detector),
      coarse_detector_(coarse(settings.detector)),
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
  if (settings_.coarse_acquisition) {
    ++counters_.coarse_searches;
    const auto coarse_found = coarse_detector_.detect(frame);
    if (!coarse_found.empty()) {
      auto found = detector_.detect(frame, around(coarse_found, settings_.search_margin_px));
      if (!found.empty()) {
        result.searched_region = true;
        return found;
      }
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
