#pragma once

// A small case written to a temporary folder: a 20 mm cube of muscle with a soft "vein" ball,
// fixed on its deepest face. Tests change case.toml to provoke errors.

#include <filesystem>
#include <string>

#include "scratch_dir.hpp"
#include "ultrasim/imaging/metaimage.hpp"

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
  explicit TinyCase(const std::string& toml = tiny_case_toml()) {
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

}  // namespace ultrasim::kiosk::testing
