// The camera tracker measured on synthetic views rendered by our own EGL renderer: the
// dodecahedron at known poses over the whole rotation sphere, with blur, noise and changing
// light; and the published cube at the same poses, to show where a cube fails.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "marker_scene.hpp"
#include "ultrasim/drivers/fiducial/camera_tracker.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/tracking/marker_body.hpp"

namespace ultrasim::drivers::fiducial {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEdgeMm = 40.0;  // the dodecahedron ultrasim-marker-select prints by default
constexpr double kCubeEdgeMm = 50.0;
constexpr int kViews = 160;

struct View {
  Eigen::Isometry3d camera_from_body;
  render::ViewLighting lighting;
  double blur_sigma_px;
  double noise_sigma;
};

// Uniformly random orientations (Shoemake), positions filling the image at 0.3–0.5 m, and a
// different light, blur and noise each time. Seeded: the same views on every run.
std::vector<View> random_views(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<View> views;
  for (int i = 0; i < count; ++i) {
    const double u1 = unit(rng), u2 = 2 * kPi * unit(rng), u3 = 2 * kPi * unit(rng);
    const Eigen::Quaterniond q(std::sqrt(u1) * std::cos(u3), std::sqrt(1 - u1) * std::sin(u2),
                               std::sqrt(1 - u1) * std::cos(u2), std::sqrt(u1) * std::sin(u3));
    View v;
    const double z = 250.0 + 200.0 * unit(rng);
    v.camera_from_body =
        Eigen::Translation3d(z * 0.25 * (2 * unit(rng) - 1), z * 0.15 * (2 * unit(rng) - 1), z) *
        q.normalized();
    v.lighting.direction_camera = Eigen::Vector3d(2 * unit(rng) - 1, 2 * unit(rng) - 1, 1.0);
    v.lighting.ambient = 0.2 + 0.3 * unit(rng);
    v.lighting.diffuse = 0.4 + 0.5 * unit(rng);
    v.lighting.background_grey = static_cast<std::uint8_t>(40 + 120 * unit(rng));
    v.blur_sigma_px = 1.0 * unit(rng);
    v.noise_sigma = 2.0 + 2.0 * unit(rng);
    views.push_back(v);
  }
  return views;
}

struct Outcome {
  int tracked = 0;
  int at_least_three = 0;
  int fewest_markers = 1000;
  double position_sq = 0.0, rotation_sq = 0.0;  // sums over tracked views
  double worst_rotation_deg = 0.0;
  int flips = 0;                     // tracked views more than 5° off
  int ambiguous = 0;                 // views resting on one marker whose two poses fit alike
  std::vector<double> rotation_deg;  // per view; NaN when not tracked
};

double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180.0 / kPi;
}

Outcome measure(const hal::MarkerBody& body, const std::vector<std::vector<Eigen::Vector3d>>& faces,
                const std::vector<View>& views, const char* png_prefix) {
  const hal::CameraIntrinsics camera = test::test_camera();
  render::OffscreenDisplay display(render::offscreen_display_settings(640, 480), {4});
  render::CameraViewRenderer renderer(test::marker_body_mesh(body, faces));
  // Per view, for the accuracy chart (scripts/plot_fiducial_accuracy.py).
  const auto dir = std::filesystem::path(ULTRASIM_BINARY_DIR) / "fiducial_views";
  std::filesystem::create_directories(dir);
  std::ofstream csv(dir / (std::string(png_prefix) + ".csv"));
  csv << "view,distance_mm,markers,tracked,position_error_mm,rotation_error_deg\n";
  Outcome out;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const View& v = views[i];
    display.begin_frame();
    renderer.draw(camera, 640, 480, v.camera_from_body, v.lighting);
    display.end_frame();
    const auto image = display.read_pixels();
    const hal::CameraFrame frame = test::camera_frame(image, v.blur_sigma_px, v.noise_sigma, i);
    if (i < 4) {
      render::write_png_grey(dir / (std::string(png_prefix) + std::to_string(i) + ".png"),
                             frame.grey, frame.width, frame.height);
    }
    CameraTrackerSettings settings;
    settings.camera = camera;
    settings.filtered = false;  // one frame, no history: the raw pipeline
    CameraTracker tracker(body, settings);
    const TrackResult r = tracker.track(frame);
    const int markers = static_cast<int>(r.body.inlier_ids.size());
    out.fewest_markers = std::min(out.fewest_markers, markers);
    if (markers >= 3) ++out.at_least_three;
    if (r.body.ambiguous || r.status == TrackStatus::kAmbiguous) ++out.ambiguous;
    const double distance_mm = v.camera_from_body.translation().norm();
    if (r.status != TrackStatus::kTracked) {
      out.rotation_deg.push_back(std::nan(""));
      csv << i << ',' << distance_mm << ',' << markers << ",0,,\n";
      continue;
    }
    ++out.tracked;
    const double position =
        (r.body.camera_from_body.translation() - v.camera_from_body.translation()).norm();
    const double rotation = rotation_error_deg(r.body.camera_from_body, v.camera_from_body);
    out.position_sq += position * position;
    out.rotation_sq += rotation * rotation;
    out.worst_rotation_deg = std::max(out.worst_rotation_deg, rotation);
    if (rotation > 5.0) ++out.flips;
    out.rotation_deg.push_back(rotation);
    csv << i << ',' << distance_mm << ',' << markers << ",1," << position << ',' << rotation
        << '\n';
  }
  return out;
}

TEST(FiducialAccuracy, DodecahedronOverTheRotationSphere) {
  const auto views = random_views(kViews, 2026);
  const auto body =
      tracking::dodecahedron_marker_body(kEdgeMm, tracking::largest_marker_side_mm(kEdgeMm));
  const Outcome d = measure(body, tracking::dodecahedron_faces(kEdgeMm), views, "dodeca");
  const double position_rms = std::sqrt(d.position_sq / std::max(d.tracked, 1));
  const double rotation_rms = std::sqrt(d.rotation_sq / std::max(d.tracked, 1));
  std::printf(
      "dodecahedron: %d/%d tracked, >=3 markers in %d, fewest %d, RMS %.3f mm %.3f deg, "
      "worst %.3f deg, flips %d\n",
      d.tracked, kViews, d.at_least_three, d.fewest_markers, position_rms, rotation_rms,
      d.worst_rotation_deg, d.flips);
  EXPECT_EQ(d.tracked, kViews);
  EXPECT_EQ(d.at_least_three, kViews);
  EXPECT_LE(position_rms, 1.0);
  EXPECT_LE(rotation_rms, 0.5);
  EXPECT_EQ(d.flips, 0);
}

// The published cube's weakness, beside the dodecahedron, over the same views: most of the time
// it shows fewer than three markers, and with one face looking straight at the camera its pose
// rests on one square, which a little noise tilts or flips (the two poses a square seen
// face-on fits). The dodecahedron at the same pose shows six faces.
TEST(FiducialAccuracy, CubeFailsWhereOneFaceLooksAtTheCamera) {
  const auto views = random_views(kViews, 2026);
  const auto cube = tracking::cube_marker_body(kCubeEdgeMm, 0.9 * kCubeEdgeMm);
  const Outcome c = measure(cube, tracking::cube_faces(kCubeEdgeMm), views, "cube");
  std::printf("cube over the sphere: %d/%d tracked, >=3 markers in %d, fewest %d\n", c.tracked,
              kViews, c.at_least_three, c.fewest_markers);
  EXPECT_LT(c.at_least_three, kViews / 2);

  // Face-on: cube face 1 and dodecahedron face 0 (both facing the body's −z) toward the camera,
  // 1° off, at 0.45 m; the same view 30 times with fresh noise.
  std::vector<View> face_on(30);
  for (auto& v : face_on) {
    v.camera_from_body =
        Eigen::Translation3d(10.0, -5.0, 450.0) *
        Eigen::AngleAxisd(1.0 * kPi / 180.0, Eigen::Vector3d(1, 1, 0).normalized());
    v.blur_sigma_px = 0.8;
    v.noise_sigma = 4.0;
  }
  const Outcome cube_face_on =
      measure(cube, tracking::cube_faces(kCubeEdgeMm), face_on, "cube-face-on");
  const auto dodecahedron =
      tracking::dodecahedron_marker_body(kEdgeMm, tracking::largest_marker_side_mm(kEdgeMm));
  const Outcome dodeca_face_on =
      measure(dodecahedron, tracking::dodecahedron_faces(kEdgeMm), face_on, "dodeca-face-on");
  const auto rms = [](const Outcome& o) {
    return std::sqrt(o.rotation_sq / std::max(o.tracked, 1));
  };
  std::printf(
      "face-on, 30 noisy frames: cube %d tracked, %d ambiguous, %d with < 3 markers, "
      "rotation RMS %.3f worst %.3f deg, flips %d; dodecahedron %d tracked, fewest %d "
      "markers, rotation RMS %.3f worst %.3f deg\n",
      cube_face_on.tracked, cube_face_on.ambiguous, 30 - cube_face_on.at_least_three,
      rms(cube_face_on), cube_face_on.worst_rotation_deg, cube_face_on.flips,
      dodeca_face_on.tracked, dodeca_face_on.fewest_markers, rms(dodeca_face_on),
      dodeca_face_on.worst_rotation_deg);
  EXPECT_GE(cube_face_on.ambiguous, 15);
  EXPECT_EQ(dodeca_face_on.tracked, 30);
  EXPECT_GE(dodeca_face_on.fewest_markers, 3);
  EXPECT_LE(rms(dodeca_face_on), 0.5);
}

// Tracking as the kiosk does: one camera, a moving probe, the search kept to the box around the
// body's last pose and the 1€ filter on. Every frame tracked, none flipped, the filtered pose
// within a few millimetres of the truth despite the filter's lag at 90°/s.
TEST(FiducialAccuracy, TracksASweepThroughEveryOrientation) {
  const hal::CameraIntrinsics camera = test::test_camera();
  const auto body =
      tracking::dodecahedron_marker_body(kEdgeMm, tracking::largest_marker_side_mm(kEdgeMm));
  render::OffscreenDisplay display(render::offscreen_display_settings(640, 480), {4});
  render::CameraViewRenderer renderer(
      test::marker_body_mesh(body, tracking::dodecahedron_faces(kEdgeMm)));
  CameraTrackerSettings settings;
  settings.camera = camera;
  CameraTracker tracker(body, settings);
  const auto poses = test::sweep_poses(240);
  double raw_sq = 0.0, raw_rot_sq = 0.0, worst_filtered_deg = 0.0, worst_filtered_mm = 0.0;
  int tracked = 0, in_region = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    display.begin_frame();
    renderer.draw(camera, 640, 480, poses[i], {});
    display.end_frame();
    hal::CameraFrame frame = test::camera_frame(display.read_pixels(), 0.6, 3.0, i);
    frame.timestamp_us = static_cast<hal::TimestampUs>(i) * 16'667;
    const TrackResult r = tracker.track(frame);
    if (r.status != TrackStatus::kTracked) continue;
    ++tracked;
    if (r.searched_region) ++in_region;
    const double e = (r.body.camera_from_body.translation() - poses[i].translation()).norm();
    const double a = rotation_error_deg(r.body.camera_from_body, poses[i]);
    raw_sq += e * e;
    raw_rot_sq += a * a;
    worst_filtered_mm = std::max(
        worst_filtered_mm, (r.patient_from_probe->translation() - poses[i].translation()).norm());
    worst_filtered_deg =
        std::max(worst_filtered_deg, rotation_error_deg(*r.patient_from_probe, poses[i]));
  }
  const auto& counters = tracker.counters();
  std::printf(
      "sweep: %d/%zu tracked (%d within the last pose's box), raw RMS %.3f mm %.3f deg, "
      "filtered worst %.2f mm %.2f deg, jumps held %llu, outlier markers %llu\n",
      tracked, poses.size(), in_region, std::sqrt(raw_sq / std::max(tracked, 1)),
      std::sqrt(raw_rot_sq / std::max(tracked, 1)), worst_filtered_mm, worst_filtered_deg,
      static_cast<unsigned long long>(counters.jumps_held),
      static_cast<unsigned long long>(counters.outlier_markers));
  EXPECT_EQ(tracked, static_cast<int>(poses.size()));
  EXPECT_GE(in_region, tracked - 1);  // all but the first frame
  EXPECT_LE(std::sqrt(raw_sq / tracked), 1.0);
  EXPECT_LE(std::sqrt(raw_rot_sq / tracked), 0.5);
  EXPECT_EQ(counters.jumps_held, 0u);
  EXPECT_LT(worst_filtered_deg, 5.0);  // no flip, only lag
}

// A probe held still, one face looking at the camera (where a single marker jitters most):
// sensor noise moves the raw fit a little each frame; the 1€ filter holds it still.
TEST(FiducialAccuracy, AStillProbeDoesNotJitter) {
  const hal::CameraIntrinsics camera = test::test_camera();
  const auto body =
      tracking::dodecahedron_marker_body(kEdgeMm, tracking::largest_marker_side_mm(kEdgeMm));
  render::OffscreenDisplay display(render::offscreen_display_settings(640, 480), {4});
  render::CameraViewRenderer renderer(
      test::marker_body_mesh(body, tracking::dodecahedron_faces(kEdgeMm)));
  const Eigen::Isometry3d pose = Eigen::Translation3d(10.0, -5.0, 400.0) *
                                 Eigen::AngleAxisd(0.02, Eigen::Vector3d(1, 1, 0).normalized());
  display.begin_frame();
  renderer.draw(camera, 640, 480, pose, {});
  display.end_frame();
  const auto image = display.read_pixels();
  CameraTrackerSettings settings;
  settings.camera = camera;
  CameraTracker tracker(body, settings);
  std::vector<Eigen::Isometry3d> raw, filtered;
  for (int i = 0; i < 90; ++i) {
    hal::CameraFrame frame = test::camera_frame(image, 0.6, 4.0, 1000 + i);
    frame.timestamp_us = i * 16'667;
    const TrackResult r = tracker.track(frame);
    ASSERT_EQ(r.status, TrackStatus::kTracked);
    if (i < 30) continue;  // the filter settling
    raw.push_back(r.body.camera_from_body);
    filtered.push_back(*r.patient_from_probe);
  }
  // Jitter: RMS angle and distance of each pose from the sequence's first.
  const auto jitter = [](const std::vector<Eigen::Isometry3d>& poses, double& mm, double& deg) {
    mm = deg = 0.0;
    for (const auto& p : poses) {
      mm += (p.translation() - poses.front().translation()).squaredNorm();
      deg += std::pow(rotation_error_deg(p, poses.front()), 2);
    }
    mm = std::sqrt(mm / poses.size());
    deg = std::sqrt(deg / poses.size());
  };
  double raw_mm, raw_deg, filtered_mm, filtered_deg;
  jitter(raw, raw_mm, raw_deg);
  jitter(filtered, filtered_mm, filtered_deg);
  std::printf("still probe, 60 frames: raw jitter %.3f mm %.3f deg, filtered %.3f mm %.3f deg\n",
              raw_mm, raw_deg, filtered_mm, filtered_deg);
  EXPECT_LT(filtered_deg, raw_deg / 2);
  EXPECT_LT(filtered_mm, raw_mm / 2);
  EXPECT_LT(filtered_deg, 0.1);
}

}  // namespace
}  // namespace ultrasim::drivers::fiducial
