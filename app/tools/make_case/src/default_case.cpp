#include "ultrasim/tools/make_case/default_case.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/tools/make_case/case_toml.hpp"

namespace ultrasim::tools {

namespace {

Eigen::Vector3i grid_size(const DefaultCaseSettings& settings) {
  if (!(settings.spacing_mm > 0.0)) throw std::invalid_argument("spacing_mm must be > 0");
  const Eigen::Vector3d extent = settings.max_mm - settings.min_mm;
  Eigen::Vector3i size;
  for (int a = 0; a < 3; ++a) {
    if (!(extent[a] > 0.0)) throw std::invalid_argument("max_mm must exceed min_mm");
    size[a] = static_cast<int>(std::lround(extent[a] / settings.spacing_mm)) + 1;
  }
  return size;
}

}  // namespace

GeneratedCase generate_default_case(const DefaultCaseSettings& settings) {
  const Eigen::Vector3i size = grid_size(settings);
  const Eigen::Vector3d spacing = Eigen::Vector3d::Constant(settings.spacing_mm);
  GeneratedCase out{imaging::Volume<std::uint8_t>(size, spacing, settings.min_mm),
                    imaging::Volume<std::uint8_t>(size, spacing, settings.min_mm)};
  const ArmPhantom phantom(settings.anatomy);

  const std::size_t n = out.labels.voxel_count();
  const std::size_t columns = static_cast<std::size_t>(size.x()) * size.y();
  std::vector<float> diffuse(n), specular(n);
  // Per beam line (x, y): mm of blood crossed so far, and depth of the first bone voxel. The
  // probe looks down +z, so walking k upwards walks each line from the skin into the body.
  std::vector<float> blood_mm(columns, 0.0f);
  std::vector<float> bone_entry_mm(columns, -1.0f);
  const float step_mm = static_cast<float>(settings.spacing_mm);
  const float bone_echo_mm = static_cast<float>(settings.anatomy.bone_echo_mm);
  auto labels = out.labels.voxels();

  std::size_t v = 0;
  for (int k = 0; k < size.z(); ++k) {
    const float z_mm = static_cast<float>(k) * step_mm;
    for (int j = 0; j < size.y(); ++j) {
      for (int i = 0; i < size.x(); ++i, ++v) {
        const std::size_t column =
            static_cast<std::size_t>(i) + static_cast<std::size_t>(size.x()) * j;
        const EchoSample e = phantom.echo_at(out.labels.index_to_world(Eigen::Vector3d(i, j, k)));
        labels[v] = e.label;
        float d = e.diffuse, s = e.specular;
        if (e.label == kBone && bone_entry_mm[column] < 0.0f) bone_entry_mm[column] = z_mm;
        const float below_echo_mm = z_mm - bone_entry_mm[column] - bone_echo_mm;
        if (bone_entry_mm[column] >= 0.0f && below_echo_mm >= 0.0f) {
          // Acoustic shadow: the cortex reflects nearly everything and nothing comes back from
          // below; the surface echo's tail (pulse length, reverberation) fades over ~0.5 mm.
          const float tail = std::exp(-below_echo_mm / 0.5f);
          d = kShadowGrey + 0.5f * d * tail;
          s *= tail * tail;
        } else if (!e.fluid && blood_mm[column] > 0.0f) {
          // Posterior enhancement: blood attenuates less than tissue, TGC over-compensates.
          d *= static_cast<float>(
              std::min(1.0 + kEnhancementPerMm * blood_mm[column], kMaxEnhancement));
        }
        if (e.fluid) blood_mm[column] += step_mm;
        diffuse[v] = d;
        specular[v] = s;
      }
    }
  }

  // Multiplicative speckle on the (slightly PSF-smoothed) mean echo, plus the specular echoes.
  // The mean echo is blurred with half the PSF only: the speckle grain already carries the PSF's
  // size, and small structures (nerve fascicles, septa) would otherwise wash out.
  const PsfSettings half_psf{settings.psf.lateral_sigma_mm / 2, settings.psf.elevation_sigma_mm / 2,
                             settings.psf.axial_sigma_mm / 2};
  blur_with_psf(diffuse, size, spacing, half_psf, KernelNorm::kUnitSum);
  blur_with_psf(specular, size, spacing, settings.psf, KernelNorm::kUnitSum);
  const std::vector<float> speckle =
      speckle_pattern(size, spacing, settings.psf, settings.speckle_seed);
  const double gamma = settings.speckle_exponent;
  const float norm = static_cast<float>(1.0 / rayleigh_power_mean(gamma));
  auto echo = out.echo.voxels();
  for (std::size_t w = 0; w < n; ++w) {
    const float s =
        gamma == 1.0 ? speckle[w] : std::pow(speckle[w], static_cast<float>(gamma)) * norm;
    const float grey = std::round(diffuse[w] * s + specular[w]);
    echo[w] = static_cast<std::uint8_t>(std::clamp(grey, 0.0f, 255.0f));
  }
  return out;
}

void write_case_folder(const std::filesystem::path& dir, const GeneratedCase& generated,
                       const ArmCaseLayout& layout) {
  std::filesystem::create_directories(dir);
  imaging::write_volume(dir / "volume.mha", generated.echo, true);
  imaging::write_volume(dir / "labels.mha", generated.labels, true);
  const std::string toml =
      default_case_toml(generated.labels.world_min_mm(), generated.labels.world_max_mm(), layout);
  const auto path = dir / "case.toml";
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file << toml;
  file.close();
  if (!file) throw std::runtime_error(path.string() + ": cannot write");
}

}  // namespace ultrasim::tools
