#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace ultrasim::hal {

// Where the kiosk's probe pose comes from. The composition root (app/kiosk main) builds the
// driver this names; everything downstream sees only a hal::PoseSource.
enum class ProbeSourceKind : std::uint8_t {
  kScripted,      // the headless run's scripted motion (drivers/sim_probe)
  kCan,           // the 3-DOF IMU probe on a SocketCAN interface (drivers/socketcan + probe_can)
  kCanReplay,     // a candump -l log of that probe, played back (drivers/can_replay + probe_can)
  kCamera,        // a camera watching the marker dodecahedron (drivers/camera + fiducial)
  kCameraImages,  // the same from a folder of recorded images
  kKeyboard,      // keyboard and mouse, for desktop development (drivers/keyboard)
};

// [probe] in app.toml. Fields a source does not use are ignored.
struct ProbeSourceSettings {
  ProbeSourceKind source = ProbeSourceKind::kScripted;

  // --- scripted: a motion file (drivers/sim_probe/motion_file.hpp) played instead of the
  // headless run's built-in script; empty: the built-in one.
  std::string motion_file;

  // --- can, can-replay: a 3-DOF IMU gives orientation only.
  std::string can_interface = "can0";
  std::string can_log;  // can-replay: the candump -l file
  double replay_speed = 1.0;
  bool replay_loop = true;
  double imu_rate_hz = 200.0;  // expected until the probe's status says otherwise
  // Where the probe's face rests in patient space, mm (it turns about this point), and how far
  // the compression input presses it in along its beam: mm per newton, up to a limit.
  std::array<double, 3> pivot_mm{0.0, 0.0, 0.0};
  double compression_mm_per_n = 1.0;
  double max_compression_mm = 20.0;

  // --- camera, camera-images: one camera watching the dodecahedron on the probe.
  std::string camera_device = "/dev/video0";
  std::string camera_images;  // camera-images: a folder of frames, played in name order
  double camera_fps = 60.0;
  int camera_width_px = 640;
  int camera_height_px = 480;
  std::array<double, 4> camera_intrinsics{600.0, 600.0, 319.5, 239.5};  // fx, fy, cx, cy, px
  std::array<double, 5> camera_distortion{};                            // k1, k2, p1, p2, k3
  // The camera in patient space and the probe's frame in the dodecahedron's, each as x, y, z
  // (mm) then a rotation vector (axis × angle, degrees).
  std::array<double, 6> camera_pose{0.0, 0.0, -400.0, 0.0, 0.0, 0.0};
  std::array<double, 6> probe_in_body{0.0, 0.0, 60.0, 0.0, 0.0, 0.0};
  double dodecahedron_edge_mm = 40.0;  // the printed net's edge (ultrasim-marker-select --net)

  // --- keyboard: the probe starts here (patient space, mm) and moves this fast.
  std::array<double, 3> keyboard_start_mm{0.0, 0.0, -5.0};
  double keyboard_speed_mm_per_s = 40.0;
  std::string keyboard_device;  // an evdev node (/dev/input/event*); empty: stdin's terminal
};

}  // namespace ultrasim::hal
