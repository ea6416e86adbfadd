// ultrasim-camera-views: renders what the kiosk's camera would see of the probe's dodecahedron
// while the probe follows a case's sweep-and-press script: numbered PNGs for [probe] source =
// "camera-images". The camera, the dodecahedron and its mount on the probe come from app.toml's
// [probe], so the kiosk tracking the frames should move its probe as the script does.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/tools/marker_mesh.hpp"
#include "ultrasim/tracking/marker_body.hpp"

namespace {

using namespace ultrasim;

int run(const std::filesystem::path& case_dir, const std::string& config_path,
        const std::filesystem::path& out_dir, double blur_px, double noise) {
  const config::AppSettings settings =
      config_path.empty() ? config::AppSettings{} : config::load_app_settings(config_path);
  const config::CaseSettings tissue = config::load_case_settings(case_dir);
  const hal::ProbeSourceSettings& p = settings.probe;
  const auto& scan = tissue.scan;
  drivers::sim_probe::ScriptedProbe script(drivers::sim_probe::sweep_press_script(
      {scan.start_mm[0], scan.start_mm[1], scan.start_mm[2]},
      {scan.end_mm[0], scan.end_mm[1], scan.end_mm[2]}, scan.press_depth_mm));

  hal::CameraIntrinsics camera;
  camera.fx_px = p.camera_intrinsics[0];
  camera.fy_px = p.camera_intrinsics[1];
  camera.cx_px = p.camera_intrinsics[2];
  camera.cy_px = p.camera_intrinsics[3];
  const Eigen::Isometry3d camera_from_patient =
      tracking::rigid_from_xyz_rotvec_deg(p.camera_pose).inverse();
  const Eigen::Isometry3d probe_from_body =
      tracking::rigid_from_xyz_rotvec_deg(p.probe_in_body).inverse();
  const double edge = p.dodecahedron_edge_mm;
  const auto body =
      tracking::dodecahedron_marker_body(edge, tracking::largest_marker_side_mm(edge));

  std::filesystem::create_directories(out_dir);
  render::OffscreenDisplay display(
      render::offscreen_display_settings(p.camera_width_px, p.camera_height_px), {4});
  render::CameraViewRenderer renderer(
      tools::marker_body_mesh(body, tracking::dodecahedron_faces(edge)));
  const auto period_us = static_cast<hal::TimestampUs>(1e6 / p.camera_fps);
  int frames = 0;
  for (hal::TimestampUs t = 0; t <= script.duration_us(); t += period_us, ++frames) {
    const hal::PoseSample probe = *script.latest(t);
    const Eigen::Isometry3d patient_from_probe =
        Eigen::Translation3d(probe.position_mm) * probe.orientation;
    display.begin_frame();
    renderer.draw(camera, p.camera_width_px, p.camera_height_px,
                  camera_from_patient * patient_from_probe * probe_from_body, {});
    display.end_frame();
    const hal::CameraFrame frame = tools::camera_frame(display.read_pixels(), blur_px, noise,
                                                       static_cast<std::uint64_t>(frames));
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.png", frames);
    render::write_png_grey(out_dir / name, frame.grey, frame.width, frame.height);
  }
  std::printf("wrote %d frames (%dx%d, %.0f fps, %.2f s of %s's sweep and press) to %s\n", frames,
              p.camera_width_px, p.camera_height_px, p.camera_fps, script.duration_us() * 1e-6,
              tissue.name.c_str(), out_dir.string().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "ultrasim camera views: what the kiosk's camera would record of the probe's dodecahedron "
      "while the probe follows a case's sweep and press (PNGs for [probe] source = "
      "\"camera-images\")"};
  std::string case_dir, config_path, out_dir;
  double blur_px = 0.6, noise = 3.0;
  app.add_option("--case", case_dir, "case folder (its [scan] gives the motion)")->required();
  app.add_option("--config", config_path, "app settings: [probe]'s camera and dodecahedron");
  app.add_option("--out", out_dir, "folder for frame_NNNNN.png")->required();
  app.add_option("--blur-px", blur_px, "Gaussian blur of each frame, px")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  app.add_option("--noise", noise, "sensor noise, grey levels (standard deviation)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    return run(case_dir, config_path, out_dir, blur_px, noise);
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-camera-views: " << e.what() << '\n';
    return 1;
  }
}
