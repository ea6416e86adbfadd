#include "ultrasim/drivers/fiducial/body_pose.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace ultrasim::drivers::fiducial {

namespace {

struct Camera {
  cv::Matx33d matrix;
  cv::Mat distortion;
};

Camera to_cv(const hal::CameraIntrinsics& c) {
  Camera out;
  out.matrix = cv::Matx33d(c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1);
  out.distortion = cv::Mat(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) out.distortion.at<double>(i) = c.distortion[i];
  return out;
}

Eigen::Isometry3d to_pose(const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  cv::Matx33d r;
  cv::Rodrigues(rvec, r);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) pose.linear()(i, j) = r(i, j);
    pose.translation()(i) = tvec[i];
  }
  return pose;
}

void to_cv(const Eigen::Isometry3d& pose, cv::Vec3d& rvec, cv::Vec3d& tvec) {
  cv::Matx33d r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = pose.linear()(i, j);
    tvec[i] = pose.translation()(i);
  }
  cv::Rodrigues(r, rvec);
}

cv::Point3d point(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

// A detection matched to its marker on the body.
struct Match {
  const hal::BodyMarker* marker;
  const TagDetection* detection;
};

// How well one marker agrees with a pose: whether it faces the camera, and its worst corner's
// reprojection error (px; infinite when it faces away).
double marker_error_px(const Match& m, const Eigen::Isometry3d& pose, const Camera& camera,
                       const BodyPoseSettings& settings, double* squared_sum = nullptr) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& c : m.marker->corners_mm) centre += c;
  centre = pose * (centre / 4.0);
  const Eigen::Vector3d normal = pose.linear() * m.marker->outward_normal;
  if (centre.z() <= 0.0 || -normal.dot(centre.normalized()) < settings.min_facing_cosine) {
    return std::numeric_limits<double>::infinity();
  }
  std::vector<cv::Point3d> object;
  for (const auto& c : m.marker->corners_mm) object.push_back(point(c));
  cv::Vec3d rvec, tvec;
  to_cv(pose, rvec, tvec);
  std::vector<cv::Point2d> image;
  cv::projectPoints(object, rvec, tvec, camera.matrix, camera.distortion, image);
  double worst = 0.0;
  for (int k = 0; k < 4; ++k) {
    const double dx = image[k].x - m.detection->corners_px[k].x();
    const double dy = image[k].y - m.detection->corners_px[k].y();
    worst = std::max(worst, std::hypot(dx, dy));
    if (squared_sum) *squared_sum += dx * dx + dy * dy;
  }
  return worst;
}

struct Score {
  int inliers = 0;
  double error = std::numeric_limits<double>::infinity();  // sum of the inliers' worst errors
  bool better_than(const Score& o) const {
    return inliers > o.inliers || (inliers == o.inliers && error < o.error);
  }
};

Score score(const std::vector<Match>& matches, const Eigen::Isometry3d& pose, const Camera& camera,
            const BodyPoseSettings& settings, double tolerance_px) {
  Score s{0, 0.0};
  for (const auto& m : matches) {
    const double e = marker_error_px(m, pose, camera, settings);
    if (e <= tolerance_px) {
      ++s.inliers;
      s.error += e;
    }
  }
  return s;
}

// Levenberg–Marquardt over the corners of the markers that agree with `pose` within tolerance.
Eigen::Isometry3d refine(const std::vector<Match>& matches, const Eigen::Isometry3d& pose,
                         const Camera& camera, const BodyPoseSettings& settings,
                         double tolerance_px) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& m : matches) {
    if (marker_error_px(m, pose, camera, settings) > tolerance_px) continue;
    for (int k = 0; k < 4; ++k) {
      object.push_back(point(m.marker->corners_mm[k]));
      image.emplace_back(m.detection->corners_px[k].x(), m.detection->corners_px[k].y());
    }
  }
  if (object.size() < 4) return pose;
  cv::Vec3d rvec, tvec;
  to_cv(pose, rvec, tvec);
  cv::Mat r(rvec), t(tvec);
  cv::solvePnPRefineLM(object, image, camera.matrix, camera.distortion, r, t);
  return to_pose(cv::Vec3d(r), cv::Vec3d(t));
}

double rotation_angle(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

}  // namespace

BodyPose estimate_body_pose(const hal::MarkerBody& body, const hal::CameraIntrinsics& intrinsics,
                            std::span<const TagDetection> detections,
                            const std::optional<Eigen::Isometry3d>& prior,
                            const BodyPoseSettings& settings) {
  BodyPose out;
  std::vector<Match> matches;
  for (const auto& d : detections) {
    const auto it = std::find_if(body.markers.begin(), body.markers.end(),
                                 [&](const hal::BodyMarker& m) { return m.id == d.id; });
    // A second detection of the same id is an outlier by nature: keep the first only.
    const bool seen = std::any_of(matches.begin(), matches.end(),
                                  [&](const Match& m) { return m.detection->id == d.id; });
    if (it == body.markers.end()) continue;
    if (seen) {
      out.outlier_ids.push_back(d.id);
      continue;
    }
    matches.push_back({&*it, &d});
  }
  if (matches.empty()) return out;
  const Camera camera = to_cv(intrinsics);

  // Hypotheses: both planar solutions of every marker alone, and the earlier pose.
  struct Hypothesis {
    Eigen::Isometry3d pose;
    int marker_id;       // the marker it was solved from; -1 for the earlier pose
    double error_ratio;  // second solution's error over the first's, for its marker
  };
  std::vector<Hypothesis> hypotheses;
  if (prior) hypotheses.push_back({*prior, -1, std::numeric_limits<double>::infinity()});
  for (const auto& m : matches) {
    // Solved in the marker's own frame (its plane at z = 0): OpenCV's IPPE gave poses 20 px off
    // for a marker whose plane, in the body's frame, did not pass through the origin.
    const auto& c = m.marker->corners_mm;
    const Eigen::Vector3d centre = (c[0] + c[1] + c[2] + c[3]) / 4.0;
    Eigen::Isometry3d body_from_marker = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d x = (c[1] - c[0]).normalized();
    const Eigen::Vector3d z = -m.marker->outward_normal;
    body_from_marker.linear().col(0) = x;
    body_from_marker.linear().col(1) = z.cross(x);
    body_from_marker.linear().col(2) = z;
    body_from_marker.translation() = centre;
    const Eigen::Isometry3d marker_from_body = body_from_marker.inverse();
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (int k = 0; k < 4; ++k) {
      Eigen::Vector3d local = marker_from_body * c[k];
      local.z() = 0.0;
      object.push_back(point(local));
      image.emplace_back(m.detection->corners_px[k].x(), m.detection->corners_px[k].y());
    }
    std::vector<cv::Mat> rvecs, tvecs;
    cv::Mat errors;
    const int n =
        cv::solvePnPGeneric(object, image, camera.matrix, camera.distortion, rvecs, tvecs, false,
                            cv::SOLVEPNP_IPPE, cv::noArray(), cv::noArray(), errors);
    for (int i = 0; i < n; ++i) {
      const double ratio =
          n == 2 ? (errors.at<double>(1) + 1e-9) / (errors.at<double>(0) + 1e-9) : 1e9;
      hypotheses.push_back({to_pose(cv::Vec3d(rvecs[i]), cv::Vec3d(tvecs[i])) * marker_from_body,
                            m.detection->id, ratio});
    }
  }

  // A single marker's solution extrapolates to the others: judge hypotheses loosely, then
  // strictly after refining the best over everything that agrees with it.
  const double loose_px = 4.0 * settings.max_corner_error_px + 4.0;
  std::size_t best = 0;
  Score best_score;
  for (std::size_t h = 0; h < hypotheses.size(); ++h) {
    const Score s = score(matches, hypotheses[h].pose, camera, settings, loose_px);
    if (s.better_than(best_score)) {
      best_score = s;
      best = h;
    }
  }
  if (best_score.inliers == 0) {
    out.status = BodyPoseStatus::kInconsistent;
    for (const auto& m : matches) out.outlier_ids.push_back(m.detection->id);
    return out;
  }
  Eigen::Isometry3d pose = refine(matches, hypotheses[best].pose, camera, settings, loose_px);
  pose = refine(matches, pose, camera, settings, settings.max_corner_error_px);

  double squared = 0.0;
  for (const auto& m : matches) {
    double s = 0.0;
    if (marker_error_px(m, pose, camera, settings, &s) <= settings.max_corner_error_px) {
      out.inlier_ids.push_back(m.detection->id);
      squared += s;
    } else {
      out.outlier_ids.push_back(m.detection->id);
    }
  }
  if (out.inlier_ids.empty()) {
    out.status = BodyPoseStatus::kInconsistent;
    return out;
  }
  if (out.inlier_ids.size() == 1) {
    // One square: its two planar solutions mirror each other about the line of sight. Trust the
    // better only when it is clearly better, or choose by the earlier pose.
    const int id = out.inlier_ids.front();
    std::vector<Eigen::Isometry3d> own;
    double ratio = 1e9;
    for (const auto& h : hypotheses) {
      if (h.marker_id != id) continue;
      own.push_back(h.pose);
      ratio = std::min(ratio, h.error_ratio);
    }
    if (ratio < settings.ambiguity_ratio) {
      out.ambiguous = true;
      if (!prior) {
        out.status = BodyPoseStatus::kAmbiguous;
        return out;
      }
      const Eigen::Isometry3d* nearest = &pose;
      for (const auto& p : own) {
        if (rotation_angle(p, *prior) < rotation_angle(*nearest, *prior)) nearest = &p;
      }
      pose = refine(matches, *nearest, camera, settings, settings.max_corner_error_px);
    }
  }
  out.status = BodyPoseStatus::kOk;
  out.camera_from_body = pose;
  out.rms_error_px = std::sqrt(squared / (4.0 * static_cast<double>(out.inlier_ids.size())));
  return out;
}

PixelRegion projected_region(const hal::MarkerBody& body, const hal::CameraIntrinsics& intrinsics,
                             const Eigen::Isometry3d& camera_from_body, double margin_px) {
  const Camera camera = to_cv(intrinsics);
  std::vector<cv::Point3d> object;
  for (const auto& m : body.markers) {
    for (const auto& c : m.corners_mm) object.push_back(point(c));
  }
  cv::Vec3d rvec, tvec;
  to_cv(camera_from_body, rvec, tvec);
  std::vector<cv::Point2d> image;
  cv::projectPoints(object, rvec, tvec, camera.matrix, camera.distortion, image);
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& p : image) {
    x0 = std::min(x0, p.x);
    y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x);
    y1 = std::max(y1, p.y);
  }
  const int left = static_cast<int>(std::floor(x0 - margin_px));
  const int top = static_cast<int>(std::floor(y0 - margin_px));
  return {left, top, static_cast<int>(std::ceil(x1 + margin_px)) - left + 1,
          static_cast<int>(std::ceil(y1 + margin_px)) - top + 1};
}

}  // namespace ultrasim::drivers::fiducial
