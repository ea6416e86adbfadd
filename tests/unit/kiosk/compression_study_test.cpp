// The compression test on the shipped default case: the vein collapses under the probe while
// the artery keeps its lumen (docs/accuracy.md, "Vein against artery").

#include "ultrasim/kiosk/compression_study.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "ultrasim/kiosk/tissue_case.hpp"

namespace ultrasim::kiosk {
namespace {

const TissueCase& default_case() {
  static const TissueCase tissue =
      load_tissue_case(std::filesystem::path(ULTRASIM_BINARY_DIR) / "cases" / "default");
  return tissue;
}

TEST(CompressionStudy, TheVeinCollapsesUnderTheProbeWhileTheArteryStaysOpen) {
  hal::InlineJobSystem jobs;
  CompressionStudyOptions options;  // the exact FEM, 0.25 mm steps
  const CompressionStudy study =
      run_compression_study(default_case(), config::AppSettings{}, options, jobs);
  ASSERT_TRUE(study.vein_collapse_force_n.has_value()) << "the vein never fell to 10 %";
  const double f_v = *study.vein_collapse_force_n;
  RecordProperty("vein_collapse_force_n", std::to_string(f_v));
  // Measured 7.4 N at 8 mm (Reuss mixing): a firm press of a 38 × 10 mm face, as sonographers use.
  EXPECT_GT(f_v, 5.0);
  EXPECT_LT(f_v, 15.0);
  const CompressionSample& rest = study.samples.front();
  for (const auto& s : study.samples) {
    if (s.force_n > f_v) break;
    EXPECT_FALSE(s.diverged) << s.depth_mm;
    // The artery keeps its lumen while the vein closes (measured ≥ 97 %).
    EXPECT_GT(s.artery_area_mm2, 0.95 * rest.artery_area_mm2) << s.depth_mm;
  }
  // The vein's lumen shrinks steadily with depth.
  for (std::size_t i = 4; i < study.samples.size() && study.samples[i].force_n <= f_v; i += 4) {
    EXPECT_LT(study.samples[i].vein_area_mm2, study.samples[i - 4].vein_area_mm2) << i;
  }
}

TEST(CompressionStudy, ACaseWithoutAVeinIsRefusedByName) {
  TissueCase tissue = default_case();
  for (auto& m : tissue.settings.materials) {
    if (m.name == "vein") m.name = "vena";
  }
  hal::InlineJobSystem jobs;
  try {
    run_compression_study(tissue, config::AppSettings{}, CompressionStudyOptions{}, jobs);
    FAIL() << "no error";
  } catch (const CaseError& e) {
    EXPECT_NE(std::string(e.what()).find("'vein'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ultrasim::kiosk
