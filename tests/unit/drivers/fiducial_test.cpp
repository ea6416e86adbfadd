#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <mutex>
#include <thread>

#include "ultrasim/drivers/fiducial/body_pose.hpp"
#include "ultrasim/drivers/fiducial/camera_pose_source.hpp"
#include "ultrasim/drivers/fiducial/pose_filter.hpp"
#include "ultrasim/tracking/marker_body.hpp"

namespace ultrasim::drivers::fiducial {
namespace {

constexpr double kPi = 3.14159265358979323846;

hal::CameraIntrinsics camera() {
  hal::CameraIntrinsics c;
  c.fx_px = c.fy_px = 600.0;
  c.cx_px = 319.5;
  c.cy_px = 239.5;
  return c;
}

// What a perfect detector reports: each marker's corners projected through the pinhole.
TagDetection project(const hal::BodyMarker& marker, const Eigen::Isometry3d& camera_from_body) {
  const auto c = camera();
  TagDetection d;
  d.id = marker.id;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = camera_from_body * marker.corners_mm[k];
    d.corners_px[k] = {c.fx_px * p.x() / p.z() + c.cx_px, c.fy_px * p.y() / p.z() + c.cy_px};
  }
  return d;
}

// The markers facing the camera by more than `min_cosine`.
std::vector<TagDetection> visible(const hal::MarkerBody& body, const Eigen::Isometry3d& pose,
                                  double min_cosine = 0.3) {
  std::vector<TagDetection> out;
  for (const auto& m : body.markers) {
    const Eigen::Vector3d centre = pose * ((m.corners_mm[0] + m.corners_mm[2]) / 2);
    if ((pose.linear() * m.outward_normal).dot(-centre.normalized()) > min_cosine)
      out.push_back(project(m, pose));
  }
  return out;
}

double angle_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180.0 / kPi;
}

const hal::MarkerBody& dodecahedron() {
  static const auto body =
      tracking::dodecahedron_marker_body(40.0, tracking::largest_marker_side_mm(40.0));
  return body;
}

Eigen::Isometry3d some_pose() {
  return Eigen::Translation3d(15.0, -10.0, 350.0) *
         Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, -0.5).normalized());
}

TEST(BodyPose, ExactCornersGiveTheExactPose) {
  const auto detections = visible(dodecahedron(), some_pose());
  ASSERT_GE(detections.size(), 3u);
  const BodyPose pose = estimate_body_pose(dodecahedron(), camera(), detections, std::nullopt);
  ASSERT_EQ(pose.status, BodyPoseStatus::kOk);
  EXPECT_EQ(pose.inlier_ids.size(), detections.size());
  EXPECT_TRUE(pose.outlier_ids.empty());
  EXPECT_LT((pose.camera_from_body.translation() - some_pose().translation()).norm(), 1e-6);
  EXPECT_LT(angle_deg(pose.camera_from_body, some_pose()), 1e-6);
  EXPECT_LT(pose.rms_error_px, 1e-6);
}

// A face on the far side cannot be seen with the near side: such a detection (a misread id, a
// reflection) is refused and the pose rests on the rest.
TEST(BodyPose, AFarSideMarkerIsAnOutlier) {
  auto detections = visible(dodecahedron(), some_pose());
  std::vector<int> seen;
  for (const auto& d : detections) seen.push_back(d.id);
  int hidden = -1;
  for (const auto& m : dodecahedron().markers) {
    if (std::find(seen.begin(), seen.end(), m.id) == seen.end()) hidden = m.id;
  }
  ASSERT_GE(hidden, 0);
  // The hidden marker's id read on top of a visible marker's corners.
  TagDetection ghost = detections.front();
  ghost.id = hidden;
  detections.push_back(ghost);
  const BodyPose pose = estimate_body_pose(dodecahedron(), camera(), detections, std::nullopt);
  ASSERT_EQ(pose.status, BodyPoseStatus::kOk);
  EXPECT_EQ(pose.outlier_ids, std::vector<int>{hidden});
  EXPECT_LT(angle_deg(pose.camera_from_body, some_pose()), 1e-6);
}

TEST(BodyPose, CornersThatDisagreeAreRefused) {
  auto detections = visible(dodecahedron(), some_pose());
  ASSERT_GE(detections.size(), 3u);
  detections[1].corners_px[2] += Eigen::Vector2d(12.0, -9.0);
  const BodyPose pose = estimate_body_pose(dodecahedron(), camera(), detections, std::nullopt);
  ASSERT_EQ(pose.status, BodyPoseStatus::kOk);
  EXPECT_EQ(pose.outlier_ids, std::vector<int>{detections[1].id});
  EXPECT_LT(angle_deg(pose.camera_from_body, some_pose()), 1e-6);
}

TEST(BodyPose, NoMarkersOfTheBody) {
  TagDetection stranger = project(dodecahedron().markers[0], some_pose());
  stranger.id = 400;
  const BodyPose pose =
      estimate_body_pose(dodecahedron(), camera(), std::vector{stranger}, std::nullopt);
  EXPECT_EQ(pose.status, BodyPoseStatus::kNoMarkers);
}

// The published cube's weakness: one face straight at the camera is one square, and a square
// seen face-on fits two poses equally (mirrored about the line of sight). Without an earlier
// pose the fit says so; with one, it takes the solution nearer it.
TEST(BodyPose, OneFaceOnSquareIsAmbiguous) {
  const auto cube = tracking::cube_marker_body(50.0, 45.0);
  // Face 1 (outward −z) toward the camera, a little off-centre.
  const Eigen::Isometry3d pose =
      Eigen::Translation3d(5.0, 3.0, 400.0) * Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitX());
  auto detections = visible(cube, pose);
  ASSERT_EQ(detections.size(), 1u);
  // A detector's corner noise (a few tenths of a pixel): exact corners would still tell the
  // two poses apart.
  const std::array<Eigen::Vector2d, 4> noise = {
      Eigen::Vector2d(0.3, -0.2), {-0.25, 0.1}, {0.2, 0.3}, {-0.1, -0.3}};
  for (int k = 0; k < 4; ++k) detections[0].corners_px[k] += noise[k];
  const BodyPose alone = estimate_body_pose(cube, camera(), detections, std::nullopt);
  EXPECT_EQ(alone.status, BodyPoseStatus::kAmbiguous);
  const Eigen::Isometry3d prior = pose * Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitY());
  const BodyPose with_prior = estimate_body_pose(cube, camera(), detections, prior);
  ASSERT_EQ(with_prior.status, BodyPoseStatus::kOk);
  EXPECT_TRUE(with_prior.ambiguous);
  // Even then a face-on square is a poor gauge of rotation: 0.3 px of noise tilts it ~6°.
  EXPECT_LT(angle_deg(with_prior.camera_from_body, pose), 10.0);
}

TEST(BodyPose, ProjectedRegionHoldsEveryMarker) {
  const PixelRegion region = projected_region(dodecahedron(), camera(), some_pose(), 10.0);
  for (const auto& d : visible(dodecahedron(), some_pose(), -1.0)) {
    for (const auto& c : d.corners_px) {
      EXPECT_GE(c.x(), region.x + 10.0);
      EXPECT_LE(c.x(), region.x + region.width - 10.0);
      EXPECT_GE(c.y(), region.y + 10.0);
      EXPECT_LE(c.y(), region.y + region.height - 10.0);
    }
  }
}

Eigen::Isometry3d at(double x_mm, double turn_rad) {
  return Eigen::Translation3d(x_mm, 0.0, 300.0) *
         Eigen::AngleAxisd(turn_rad, Eigen::Vector3d::UnitZ());
}

TEST(PoseFilter, FirstSamplePassesAndAStillPoseStays) {
  PoseFilter filter;
  const Eigen::Isometry3d pose = at(10.0, 0.3);
  EXPECT_TRUE(filter.update(pose, 1'000).isApprox(pose));
  for (int i = 1; i <= 10; ++i) EXPECT_TRUE(filter.update(pose, 1'000 + i * 16'667).isApprox(pose));
}

// At rest the filter cuts jitter: ±0.5 mm alternating noise comes out far smaller.
TEST(PoseFilter, JitterAtRestIsDamped) {
  PoseFilter filter;
  double worst = 0.0;
  for (int i = 0; i < 120; ++i) {
    const double noise = (i % 2 == 0 ? 0.5 : -0.5);
    const auto out = filter.update(at(noise, 0.0), i * 16'667);
    if (i > 30) worst = std::max(worst, std::abs(out.translation().x()));
  }
  EXPECT_LT(worst, 0.15);
}

// A steady move (100 mm/s, 90°/s) is followed with little lag once the speed is known.
TEST(PoseFilter, FollowsASteadyMove) {
  PoseFilter filter;
  Eigen::Isometry3d out;
  for (int i = 0; i <= 60; ++i) {
    const double t = i / 60.0;
    out = filter.update(at(100.0 * t, 0.5 * kPi * t), i * 16'667);
  }
  EXPECT_LT(std::abs(out.translation().x() - 100.0), 6.0);
  EXPECT_LT(angle_deg(out, at(100.0, 0.5 * kPi)), 6.0);
  filter.reset();
  EXPECT_TRUE(filter.update(at(0.0, 0.0), 2'000'000).isApprox(at(0.0, 0.0)));
}

// A frame source a test feeds by hand.
class FakeFrames final : public hal::FrameSource {
 public:
  void push(hal::CameraFrame frame) {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(frame));
  }
  void fail() { health_ = hal::FrameSourceHealth::kFault; }
  bool next_frame(hal::CameraFrame& frame, hal::TimestampUs timeout_us) override {
    for (int i = 0; i < 10; ++i) {
      {
        std::lock_guard lock(mutex_);
        if (!queue_.empty() && health_ == hal::FrameSourceHealth::kOk) {
          frame = std::move(queue_.front());
          queue_.erase(queue_.begin());
          return true;
        }
      }
      std::this_thread::sleep_for(std::chrono::microseconds(timeout_us / 10));
    }
    return false;
  }
  hal::FrameSourceHealth health() const override { return health_; }
  std::string_view status() const override {
    return health_ == hal::FrameSourceHealth::kFault ? "unplugged" : "";
  }
  std::string_view name() const override { return "fake"; }

 private:
  std::mutex mutex_;
  std::vector<hal::CameraFrame> queue_;
  std::atomic<hal::FrameSourceHealth> health_{hal::FrameSourceHealth::kOk};
};

void wait_for(const CameraPoseSource& source, std::uint64_t frames) {
  for (int i = 0; i < 500 && source.frames_done() < frames; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_GE(source.frames_done(), frames);
}

// No markers in view: nothing to report yet; the camera going away is a fault, not a crash.
TEST(CameraPoseSource, BlankFramesGiveNoPoseAndAFaultIsReported) {
  FakeFrames frames;
  CameraTrackerSettings settings;
  settings.camera = camera();
  hal::ManualClock clock;
  CameraPoseSource source(frames, std::make_unique<CameraTracker>(dodecahedron(), settings), clock);
  for (int i = 0; i < 3; ++i) {
    hal::CameraFrame blank{i * 33'333, static_cast<std::uint32_t>(i), 640, 480,
                           std::vector<std::uint8_t>(640 * 480, 128)};
    frames.push(blank);
  }
  wait_for(source, 3);
  EXPECT_FALSE(source.latest(100'000).has_value());
  EXPECT_EQ(source.status_text(), "camera: no markers in view");
  EXPECT_EQ(source.status().counters.no_markers, 3u);
  EXPECT_EQ(source.status().last_status, TrackStatus::kNoMarkers);
  frames.fail();
  for (int i = 0; i < 100 && source.status().camera != hal::FrameSourceHealth::kFault; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(source.status().camera, hal::FrameSourceHealth::kFault);
  EXPECT_EQ(source.status().camera_status, "unplugged");
  source.latest(200'000);
  EXPECT_EQ(source.status_text(), "camera: unplugged");
}

}  // namespace
}  // namespace ultrasim::drivers::fiducial
