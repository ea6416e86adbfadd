// ultrasim-make-case: writes the embedded default case (volume.mha, labels.mha, case.toml).
// The build runs it to produce build/<preset>/cases/default/; see docs/case-format.md.

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>

#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/tools/make_case/default_case.hpp"
#include "ultrasim/tools/make_case/volume_case.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "Generate an ultrasim case: the default synthetic upper arm, or (--from-volume) a case "
      "around a real reconstructed 3D ultrasound volume"};
  std::filesystem::path out_dir;
  double spacing_mm = 0.25;
  double speckle_exponent = ultrasim::tools::DefaultCaseSettings{}.speckle_exponent;
  bool quiet = false;
  bool large = false;
  std::filesystem::path from_volume;
  std::string name = "real-volume";
  app.add_option("--out", out_dir, "output folder (created if missing)")->required();
  app.add_option("--spacing-mm", spacing_mm, "isotropic voxel size in mm")
      ->check(CLI::Range(0.05, 5.0));
  app.add_option("--speckle-exponent", speckle_exponent,
                 "speckle compression: 1 = raw Rayleigh envelope, <1 = log-compressed look")
      ->check(CLI::Range(0.1, 1.0));
  app.add_flag("--quiet", quiet, "print nothing on success");
  app.add_flag("--large", large,
               "the large case instead: the arm over 120 x 120 x 45 mm at 0.5 mm (unless "
               "--spacing-mm), meshed as 25 stitched sub-volumes of 15^3 nodes");
  app.add_option("--from-volume", from_volume,
                 "make a one-tissue case around this real volume (.mha) instead")
      ->check(CLI::ExistingFile);
  app.add_option("--name", name, "case name for --from-volume");
  CLI11_PARSE(app, argc, argv);

  try {
    if (!from_volume.empty()) {
      const auto volume = ultrasim::imaging::read_volume_u8(from_volume);
      ultrasim::tools::VolumeCaseSettings settings;
      settings.name = name;
      settings.description = "made by ultrasim-make-case from " + from_volume.filename().string() +
                             "; one homogeneous tissue (not segmented)";
      const auto made = ultrasim::tools::make_volume_case(volume, settings);
      ultrasim::tools::write_volume_case(out_dir, volume, made);
      if (!quiet)
        std::printf("ultrasim-make-case: %s: case '%s'\n", out_dir.string().c_str(), name.c_str());
      return 0;
    }
    const auto start = std::chrono::steady_clock::now();
    ultrasim::tools::DefaultCaseSettings settings;
    ultrasim::tools::ArmCaseLayout layout;
    if (large) {
      settings.min_mm = {-60.0, -60.0, 0.0};
      settings.max_mm = {60.0, 60.0, 45.0};
      if (app.count("--spacing-mm") == 0) spacing_mm = 0.5;
      layout = ultrasim::tools::large_arm_layout();
    }
    settings.spacing_mm = spacing_mm;
    settings.speckle_exponent = speckle_exponent;
    const auto generated = ultrasim::tools::generate_default_case(settings);
    ultrasim::tools::write_case_folder(out_dir, generated, layout);
    const double elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!quiet) {
      const auto& n = generated.echo.size();
      std::printf("ultrasim-make-case: %s: %d x %d x %d voxels at %.3g mm in %.2f s\n",
                  out_dir.string().c_str(), n.x(), n.y(), n.z(), spacing_mm, elapsed_s);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ultrasim-make-case: %s\n", e.what());
    return 1;
  }
  return 0;
}
