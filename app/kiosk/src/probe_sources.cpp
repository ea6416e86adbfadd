#include "ultrasim/kiosk/probe_sources.hpp"

#include <Eigen/Geometry>
#include <stdexcept>

#include "ultrasim/drivers/camera/image_sequence.hpp"
#include "ultrasim/drivers/camera/v4l2_camera.hpp"
#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/can_replay/replay_bus.hpp"
#include "ultrasim/drivers/fiducial/camera_pose_source.hpp"
#include "ultrasim/drivers/keyboard/keyboard_probe.hpp"
#include "ultrasim/drivers/probe_can/can_probe.hpp"
#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"
#include "ultrasim/tracking/marker_body.hpp"

namespace ultrasim::kiosk {

namespace {

std::unique_ptr<hal::PoseSource> can_probe(const hal::ProbeSourceSettings& s, hal::CanBus& bus,
                                           std::string name) {
  drivers::probe_can::CanProbeSettings settings;
  settings.name = std::move(name);
  settings.expected_rate_hz = s.imu_rate_hz;
  settings.position_mm = Eigen::Vector3d(s.pivot_mm[0], s.pivot_mm[1], s.pivot_mm[2]);
  settings.compression_mm_per_n = s.compression_mm_per_n;
  settings.max_compression_mm = s.max_compression_mm;
  return std::make_unique<drivers::probe_can::CanProbe>(bus, settings);
}

std::unique_ptr<hal::PoseSource> camera_tracker(
    const hal::ProbeSourceSettings& s, hal::FrameSource& frames, const hal::Clock& clock,
    std::string name, drivers::fiducial::CameraPoseSource::Threading threading) {
  drivers::fiducial::CameraTrackerSettings settings;
  settings.camera.fx_px = s.camera_intrinsics[0];
  settings.camera.fy_px = s.camera_intrinsics[1];
  settings.camera.cx_px = s.camera_intrinsics[2];
  settings.camera.cy_px = s.camera_intrinsics[3];
  settings.camera.distortion = s.camera_distortion;
  settings.patient_from_camera = tracking::rigid_from_xyz_rotvec_deg(s.camera_pose);
  settings.body_from_probe = tracking::rigid_from_xyz_rotvec_deg(s.probe_in_body);
  const double edge = s.dodecahedron_edge_mm;
  auto tracker = std::make_unique<drivers::fiducial::CameraTracker>(
      tracking::dodecahedron_marker_body(edge, tracking::largest_marker_side_mm(edge)), settings);
  return std::make_unique<drivers::fiducial::CameraPoseSource>(frames, std::move(tracker), clock,
                                                               std::move(name), threading);
}

}  // namespace

const char* probe_source_key(hal::ProbeSourceKind kind) {
  switch (kind) {
    case hal::ProbeSourceKind::kScripted:
      return "scripted";
    case hal::ProbeSourceKind::kCan:
      return "can";
    case hal::ProbeSourceKind::kCanReplay:
      return "can-replay";
    case hal::ProbeSourceKind::kCamera:
      return "camera";
    case hal::ProbeSourceKind::kCameraImages:
      return "camera-images";
    case hal::ProbeSourceKind::kKeyboard:
      return "keyboard";
  }
  return "?";
}

ProbeSource make_probe_source(const hal::ProbeSourceSettings& s,
                              std::vector<drivers::sim_probe::Keyframe> keyframes,
                              const hal::Clock& script_clock, const hal::Clock& real_clock) {
  ProbeSource out;
  switch (s.source) {
    case hal::ProbeSourceKind::kScripted:
      out.pose = std::make_unique<drivers::sim_probe::ScriptedProbe>(std::move(keyframes));
      break;
    case hal::ProbeSourceKind::kCanReplay: {
      if (s.can_log.empty()) {
        throw std::invalid_argument(
            "[probe] source = \"can-replay\" needs can_log (a candump -l "
            "file)");
      }
      out.bus = std::make_unique<drivers::can_replay::ReplayBus>(
          drivers::can_replay::read_candump_log(s.can_log), script_clock,
          drivers::can_replay::ReplayBus::Options{s.replay_speed, s.replay_loop});
      out.pose = can_probe(s, *out.bus, "replay");
      break;
    }
    case hal::ProbeSourceKind::kCan:
      out.bus = std::make_unique<drivers::socketcan::SocketCanBus>(s.can_interface, real_clock);
      out.pose = can_probe(s, *out.bus, s.can_interface);
      out.real_time = true;
      break;
    case hal::ProbeSourceKind::kCamera: {
      drivers::camera::V4l2CameraSettings camera;
      camera.device = s.camera_device;
      camera.width_px = s.camera_width_px;
      camera.height_px = s.camera_height_px;
      camera.frames_per_second = s.camera_fps;
      out.frames = std::make_unique<drivers::camera::V4l2CameraSource>(camera, real_clock);
      out.pose = camera_tracker(s, *out.frames, real_clock, "camera " + s.camera_device,
                                drivers::fiducial::CameraPoseSource::Threading::kOwnThread);
      out.real_time = true;
      break;
    }
    case hal::ProbeSourceKind::kCameraImages: {
      if (s.camera_images.empty()) {
        throw std::invalid_argument(
            "[probe] source = \"camera-images\" needs camera_images (a folder of frames)");
      }
      drivers::camera::ImageSequenceSettings images;
      images.frames_per_second = s.camera_fps;
      out.frames = std::make_unique<drivers::camera::ImageSequenceSource>(
          std::filesystem::path(s.camera_images), script_clock, images);
      // Tracked in step with the run's virtual clock: the same on every machine.
      out.pose = camera_tracker(s, *out.frames, script_clock, "camera images",
                                drivers::fiducial::CameraPoseSource::Threading::kCallerThread);
      break;
    }
    case hal::ProbeSourceKind::kKeyboard: {
      drivers::keyboard::KeyboardProbeSettings keys;
      keys.start_mm =
          Eigen::Vector3d(s.keyboard_start_mm[0], s.keyboard_start_mm[1], s.keyboard_start_mm[2]);
      keys.speed_mm_per_s = s.keyboard_speed_mm_per_s;
      out.pose = drivers::keyboard::open_keyboard_probe(s.keyboard_device, keys);
      out.real_time = true;
      break;
    }
  }
  return out;
}

}  // namespace ultrasim::kiosk
