#include "ultrasim/kiosk/compression_study.hpp"

#include <cmath>
#include <fstream>
#include <stdexcept>

#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/imaging/cross_section.hpp"
#include "ultrasim/kiosk/session.hpp"

namespace ultrasim::kiosk {

namespace {

std::uint8_t label_named(const TissueCase& tissue, const std::string& name) {
  for (const auto& m : tissue.settings.materials) {
    if (m.name == name) return static_cast<std::uint8_t>(m.label);
  }
  throw CaseError(tissue.settings.name + ": the compression study needs a material named '" + name +
                  "'");
}

// The image plane through the probe (lateral x, depth z at the probe's y), over the whole case.
imaging::PlaneRegion image_plane(const TissueCase& tissue, double y_mm) {
  const Eigen::Vector3d lo = tissue.volume.world_min_mm(), hi = tissue.volume.world_max_mm();
  imaging::PlaneRegion plane;
  plane.origin_mm = Eigen::Vector3d(lo.x(), y_mm, lo.z());
  plane.extent_u_mm = hi.x() - lo.x();
  plane.extent_v_mm = hi.z() - lo.z();
  plane.step_mm = 0.2;
  return plane;
}

}  // namespace

CompressionStudy run_compression_study(const TissueCase& tissue,
                                       const config::AppSettings& settings,
                                       const CompressionStudyOptions& options,
                                       hal::JobSystem& jobs) {
  const std::uint8_t vein = label_named(tissue, "vein");
  const std::uint8_t artery = label_named(tissue, "artery");
  config::AppSettings study_settings = settings;
  study_settings.sim.method = options.method;
  hal::ManualClock clock;
  Session session(tissue, study_settings, clock, jobs);
  geometry::TetLocator locator(tissue.mesh);

  const auto& scan = tissue.settings.scan;
  const Eigen::Vector3d middle(0.5 * (scan.start_mm[0] + scan.end_mm[0]),
                               0.5 * (scan.start_mm[1] + scan.end_mm[1]),
                               0.5 * (scan.start_mm[2] + scan.end_mm[2]));
  const imaging::PlaneRegion plane = image_plane(tissue, middle.y());

  CompressionStudy study;
  study.method = std::string(sim::engine_key(options.method));
  const int steps = static_cast<int>(std::floor(options.max_depth_mm / options.step_mm + 1e-9));
  for (int step = 0; step <= steps; ++step) {
    hal::PoseSample pose;
    pose.position_mm = middle + Eigen::Vector3d(0, 0, step * options.step_mm);
    FrameOutcome outcome;
    for (int f = 0; f < options.frames_per_step; ++f) {
      pose.timestamp_us = clock.now_us();
      outcome = session.update(pose);
      clock.advance_us(16'667);
    }
    locator.rebuild(session.engine_positions_mm());
    CompressionSample s;
    s.depth_mm = step * options.step_mm;
    s.force_n = outcome.sim.contact_force_n;
    s.vein_area_mm2 =
        imaging::deformed_label_area_mm2(tissue.labels, tissue.mesh, locator, plane, vein);
    s.artery_area_mm2 =
        imaging::deformed_label_area_mm2(tissue.labels, tissue.mesh, locator, plane, artery);
    s.inverted_tets = outcome.sim.inverted_tets;
    s.diverged = outcome.sim.diverged;
    study.samples.push_back(s);
    if (options.on_sample) options.on_sample(s);
  }

  const CompressionSample& rest = study.samples.front();
  for (const auto& s : study.samples) {
    if (s.vein_area_mm2 <= 0.1 * rest.vein_area_mm2 && !s.diverged) {
      study.vein_collapse_force_n = s.force_n;
      break;
    }
  }
  if (study.vein_collapse_force_n) {
    const double target = 3.0 * *study.vein_collapse_force_n;
    for (const auto& s : study.samples) {
      if (s.force_n >= target && !s.diverged) {
        study.artery_fraction_at_3fv = s.artery_area_mm2 / rest.artery_area_mm2;
        break;
      }
    }
  }
  return study;
}

void write_compression_csv(const std::filesystem::path& path, const CompressionStudy& study) {
  std::ofstream out(path);
  out << "# method " << study.method << "\n";
  out << "depth_mm,force_n,vein_area_mm2,artery_area_mm2,inverted_tets,diverged\n";
  for (const auto& s : study.samples) {
    out << s.depth_mm << ',' << s.force_n << ',' << s.vein_area_mm2 << ',' << s.artery_area_mm2
        << ',' << s.inverted_tets << ',' << (s.diverged ? 1 : 0) << '\n';
  }
  if (!out) throw std::runtime_error(path.string() + ": cannot write the compression study");
}

}  // namespace ultrasim::kiosk
