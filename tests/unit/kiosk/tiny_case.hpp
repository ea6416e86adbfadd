#pragma once

// A small case written to a temporary folder: a 20 mm cube of muscle with a soft "vein" ball,
// fixed on its deepest face. Tests change case.toml to provoke errors. And a fixture with it
// loaded.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "scratch_dir.hpp"
#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/hal/pose_sample.hpp"
#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/kiosk/tissue_case.hpp"

namespace ultrasim::kiosk::testing {

inline std::string tiny_case_toml(const std::string& fixed_faces = "[\"z_max\"]",
                                  bool with_vein_material = true,
                                  const std::string& probe = "width_mm = 16.0\ndepth_mm = 16.0\n") {
  std::string toml = R"([case]
name = "tiny"
volume = "volume.mha"
labels = "labels.mha"

[mesh]
nodes = [5, 5, 5]
fixed_faces = )" + fixed_faces +
                     R"(

[[materials]]
label = 3
name = "muscle"
youngs_modulus_kpa = 50.0
)";
  if (with_vein_material) {
    toml += R"(
[[materials]]
label = 4
name = "vein"
youngs_modulus_kpa = 1.0
poisson_ratio = 0.05
)";
  }
  toml += R"(
[probe]
)" + probe +
          R"(
[scan]
start_mm = [0.0, -5.0, 0.0]
end_mm = [0.0, 5.0, 0.0]
press_depth_mm = 3.0
)";
  return toml;
}

class TinyCase {
 public:
  explicit TinyCase(const std::string& toml = tiny_case_toml(), std::string_view tag = {})
      : scratch_(tag) {
    imaging::Volume<std::uint8_t> echo({21, 21, 21}, {1, 1, 1}, {-10, -10, 0});
    imaging::Volume<std::uint8_t> labels({21, 21, 21}, {1, 1, 1}, {-10, -10, 0});
    for (int k = 0; k < 21; ++k)
      for (int j = 0; j < 21; ++j)
        for (int i = 0; i < 21; ++i) {
          const Eigen::Vector3d p = echo.index_to_world({double(i), double(j), double(k)});
          const bool vein = (p - Eigen::Vector3d(0, p.y(), 8)).norm() < 4.0;
          labels.at(i, j, k) = vein ? 4 : 3;
          echo.at(i, j, k) =
              vein ? 2 : static_cast<std::uint8_t>(60 + (i * 7 + j * 13 + k * 5) % 50);
        }
    imaging::write_volume(scratch_ / "volume.mha", echo);
    imaging::write_volume(scratch_ / "labels.mha", labels);
    scratch_.write("case.toml", toml);
  }
  const std::filesystem::path& dir() const { return scratch_.path(); }

 private:
  ::ultrasim::testing::ScratchDir scratch_;
};

// The probe straight down over the tiny case's centre, its face `depth_mm` below the skin.
inline hal::PoseSample pose_at(double depth_mm) {
  hal::PoseSample s;
  s.position_mm = {0.0, 0.0, depth_mm};
  return s;
}

// A test with the tiny case loaded, small B-scans and a manual clock, for sessions and the
// frame loop.
class TinyCaseTest : public ::testing::Test {
 protected:
  TinyCaseTest() : tissue_(load_tissue_case(files_.dir())) {
    settings_.bscan.width_px = 64;
    settings_.bscan.height_px = 64;
    settings_.fem.pcg_iterations_per_frame = 200;
  }
  TinyCase files_;
  TissueCase tissue_;
  config::AppSettings settings_;
  hal::ManualClock clock_;
  hal::InlineJobSystem jobs_;
};

}  // namespace ultrasim::kiosk::testing
