#include "ultrasim/tools/make_case/volume_case.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::tools {

namespace {

constexpr int kTissueLabel = 3;

}  // namespace

VolumeCase make_volume_case(const imaging::Volume<std::uint8_t>& volume,
                            const VolumeCaseSettings& s) {
  if (!volume.direction().isIdentity(1e-9)) {
    throw std::invalid_argument("volume case: only axis-aligned volumes are supported");
  }
  // Where each (x, y) column's data starts: the sweep's ragged top edge. Zero voxels below it
  // are data too (shadows are black), so the column top, not each voxel, tells tissue from none.
  const Eigen::Vector3i n = volume.size();
  std::vector<int> column_top(static_cast<std::size_t>(n.x()) * n.y(), -1);
  Eigen::Vector3i lo = n, hi = Eigen::Vector3i::Constant(-1);
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i)
        if (volume.at(i, j, k) > 0) {
          int& top = column_top[static_cast<std::size_t>(j) * n.x() + i];
          if (top < 0) top = k;
          lo = lo.cwiseMin(Eigen::Vector3i(i, j, k));
          hi = hi.cwiseMax(Eigen::Vector3i(i, j, k));
        }
  if ((hi.array() < 0).any()) throw std::invalid_argument("volume case: the volume holds no data");

  const Eigen::Vector3d spacing = volume.spacing_mm();
  // Columns whose data starts near the typical skin depth: the body of the sweep, without the
  // slanted first and last frames whose data only begins deep down.
  std::vector<int> data_tops;
  for (int top : column_top)
    if (top >= 0) data_tops.push_back(top);
  std::nth_element(data_tops.begin(), data_tops.begin() + data_tops.size() / 2, data_tops.end());
  const int median_top = data_tops[data_tops.size() / 2];
  const int near_skin = median_top + static_cast<int>(std::ceil(3.0 / spacing.z()));
  Eigen::Vector3i box_lo = n, box_hi = Eigen::Vector3i::Constant(-1);
  for (int j = 0; j < n.y(); ++j)
    for (int i = 0; i < n.x(); ++i) {
      const int top = column_top[static_cast<std::size_t>(j) * n.x() + i];
      if (top < 0 || top > near_skin) continue;
      box_lo = box_lo.cwiseMin(Eigen::Vector3i(i, j, 0));
      box_hi = box_hi.cwiseMax(Eigen::Vector3i(i, j, hi.z()));
    }
  const Eigen::Vector3i margin =
      (Eigen::Vector3d::Constant(s.margin_mm).cwiseQuotient(spacing)).array().ceil().cast<int>();
  box_lo += margin;
  box_hi -= margin;
  if ((box_hi.array() <= box_lo.array()).any()) {
    throw std::invalid_argument("volume case: the data is thinner than twice the margin");
  }
  // The probe rests at the depth by which `min_coverage` of the columns hold tissue.
  std::vector<int> tops;
  for (int j = box_lo.y(); j <= box_hi.y(); ++j)
    for (int i = box_lo.x(); i <= box_hi.x(); ++i) {
      const int top = column_top[static_cast<std::size_t>(j) * n.x() + i];
      tops.push_back(top < 0 ? n.z() : top);
    }
  const auto rank = static_cast<std::size_t>(std::clamp(s.min_coverage, 0.0, 1.0) *
                                             static_cast<double>(tops.size() - 1));
  std::nth_element(tops.begin(), tops.begin() + static_cast<std::ptrdiff_t>(rank), tops.end());
  box_lo.z() = tops[rank];
  if (box_lo.z() >= box_hi.z()) {
    throw std::invalid_argument("volume case: too few columns of the volume hold data");
  }

  const auto world = [&](const Eigen::Vector3i& index) {
    return volume.index_to_world(index.cast<double>());
  };
  const Eigen::Vector3d region_min = world(box_lo), region_max = world(box_hi);
  const Eigen::Vector3d extent = region_max - region_min;

  VolumeCase c;
  auto& cs = c.settings;
  cs.name = s.name;
  cs.description = s.description;
  cs.volume_path = "volume.mha";
  cs.labels_path = "labels.mha";
  for (int a = 0; a < 3; ++a) {
    cs.mesh.nodes[a] =
        std::clamp(static_cast<int>(std::lround(extent[a] / s.node_spacing_mm)) + 1, 2, 512);
  }
  cs.mesh.region_min_mm = std::array<double, 3>{region_min.x(), region_min.y(), region_min.z()};
  cs.mesh.region_max_mm = std::array<double, 3>{region_max.x(), region_max.y(), region_max.z()};
  cs.mesh.fixed_faces = {config::BoxFace::kZMax};
  cs.materials = {
      sim::Material{kTissueLabel, "soft tissue", s.youngs_modulus_kpa, s.poisson_ratio}};
  cs.probe.kind = imaging::ProbeKind::kLinear;
  cs.probe.width_mm = std::min(s.probe_width_mm, std::floor(extent.x() - 2.0));
  cs.probe.depth_mm = std::min(s.probe_depth_mm, std::floor(extent.z()));
  const double sweep_margin_mm = std::min(5.0, extent.y() / 4);
  const double x_mid = (region_min.x() + region_max.x()) / 2;
  cs.scan.start_mm = {x_mid, region_min.y() + sweep_margin_mm, region_min.z()};
  cs.scan.end_mm = {x_mid, region_max.y() - sweep_margin_mm, region_min.z()};
  cs.scan.press_depth_mm = s.press_depth_mm;

  c.labels = imaging::Volume<std::uint8_t>(volume.size(), volume.spacing_mm(), volume.origin_mm(),
                                           volume.direction());
  std::fill(c.labels.voxels().begin(), c.labels.voxels().end(), std::uint8_t{kTissueLabel});
  return c;
}

void write_volume_case(const std::filesystem::path& dir,
                       const imaging::Volume<std::uint8_t>& volume, const VolumeCase& c) {
  std::filesystem::create_directories(dir);
  imaging::write_volume(dir / "volume.mha", volume);
  imaging::write_volume(dir / "labels.mha", c.labels);
  std::ofstream out(dir / "case.toml");
  out << config::format_case_toml(c.settings, dir);
  if (!out) throw std::runtime_error((dir / "case.toml").string() + ": cannot write");
}

}  // namespace ultrasim::tools
