// The vein law on the shipped default case, under large strain (docs/accuracy.md, "Vein against
// artery").

#include <gtest/gtest.h>

#include <filesystem>

#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/kiosk/compression_study.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"

namespace ultrasim::kiosk {
namespace {

// The vein law (issue 3): the vein at ≤ 10 % of its lumen at some force F_v while the artery
// keeps ≥ 80 % at 3·F_v. The linear methods refuse frames past ~12 N (the face's rim inverts
// tets), below 3·F_v; the hyperelastic FEM, whose tissue stiffens as it is squeezed, reaches it.
// 3-6 min on 2 cores (21 hyperelastic frames on the 37 × 9 × 28 mesh): its own executable, with
// its own time limit.
TEST(VeinLaw, UnderLargeStrainTheArteryKeepsFourFifthsOfItsLumenAtThreeTimesTheClosingForce) {
  drivers::posix::ThreadPool jobs(2);  // the kiosk's two threads
  CompressionStudyOptions options;
  options.method = sim::EngineKind::kHyperelasticFem;
  options.step_mm = 1.0;
  options.max_depth_mm = 21.0;
  const CompressionStudy study = run_compression_study(
      load_tissue_case(std::filesystem::path(ULTRASIM_BINARY_DIR) / "cases" / "default"),
      config::AppSettings{}, options, jobs);
  ASSERT_TRUE(study.vein_collapse_force_n.has_value()) << "the vein never fell to 10 %";
  const double f_v = *study.vein_collapse_force_n;
  RecordProperty("vein_collapse_force_n", std::to_string(f_v));
  EXPECT_GT(f_v, 5.0);  // measured 12.6 N at 10 mm
  EXPECT_LT(f_v, 20.0);
  ASSERT_TRUE(study.artery_fraction_at_3fv.has_value()) << "3 F_v not reached by 21 mm";
  RecordProperty("artery_fraction_at_3fv", std::to_string(*study.artery_fraction_at_3fv));
  EXPECT_GE(*study.artery_fraction_at_3fv, 0.80);  // measured 80.4 % at 21 mm, 39.6 N
  for (const auto& s : study.samples) {
    if (s.force_n > 3.0 * f_v) break;
    EXPECT_FALSE(s.diverged) << s.depth_mm;
    EXPECT_EQ(s.inverted_tets, 0) << s.depth_mm;
  }
}

}  // namespace
}  // namespace ultrasim::kiosk
