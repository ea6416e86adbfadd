#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

// The compression test a sonographer does to tell a vein from an artery: press the probe straight
// down over both and watch the lumens. The probe (the case's, as the configured collider) presses
// at the middle of the case's scan line in small steps; at each depth the probe force and the
// vein's and artery's lumen areas in the image plane are measured (from the labels, mapped
// through the deformed mesh).
struct CompressionSample {
  double depth_mm = 0.0;
  double force_n = 0.0;
  double vein_area_mm2 = 0.0;
  double artery_area_mm2 = 0.0;
  int inverted_tets = 0;
  bool diverged = false;
};

struct CompressionStudyOptions {
  sim::EngineKind method = sim::EngineKind::kExactFem;
  double max_depth_mm = 15.0;
  double step_mm = 0.25;
  // Frames simulated at each depth (quasi-static methods settle in one; dynamic ones need more).
  int frames_per_step = 1;
  // Called with each sample as it is measured (the slow methods take seconds a step).
  std::function<void(const CompressionSample&)> on_sample;
};

struct CompressionStudy {
  std::string method;
  std::vector<CompressionSample> samples;  // the first at depth 0 (touching, no press)
  // The vein law: the least force at which the vein keeps ≤ 10 % of its lumen (F_v), and the
  // artery's lumen fraction at the sample nearest 3·F_v (nullopt: not reached in the study).
  std::optional<double> vein_collapse_force_n;
  std::optional<double> artery_fraction_at_3fv;
};

// Runs the study. Throws CaseError when the case has no material named "vein" or "artery".
CompressionStudy run_compression_study(const TissueCase& tissue,
                                       const config::AppSettings& settings,
                                       const CompressionStudyOptions& options,
                                       hal::JobSystem& jobs);

// Writes the samples as CSV (depth_mm, force_n, vein_area_mm2, artery_area_mm2, inverted_tets,
// diverged). Throws std::runtime_error naming the path on failure.
void write_compression_csv(const std::filesystem::path& path, const CompressionStudy& study);

}  // namespace ultrasim::kiosk
