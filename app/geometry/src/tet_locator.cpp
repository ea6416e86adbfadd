#include "ultrasim/geometry/tet_locator.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "ultrasim/geometry/tet_edges.hpp"

namespace ultrasim::geometry {

namespace {
constexpr double kBarycentricTolerance = 1e-9;
}

TetLocator::TetLocator(const TetMesh& mesh)
    : tets_(mesh.tets),
      origin_(mesh.tets.size()),
      inverse_(mesh.tets.size()),
      usable_(mesh.tets.size(), 0),
      tet_bin_range_(mesh.tets.size()) {
  rebuild(mesh.rest_positions_mm);
}

void TetLocator::rebuild(std::span<const Eigen::Vector3d> positions_mm) {
  const std::size_t tet_count = tets_.size();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  degenerate_tets_ = 0;
  double mean_extent = 0.0;
  for (std::size_t t = 0; t < tet_count; ++t) {
    const Tet& tet = tets_[t];
    const Eigen::Vector3d& p0 = positions_mm[tet[0]];
    const Eigen::Matrix3d edges = tet_edge_matrix(positions_mm, tet);
    usable_[t] = usable_tet(edges);
    if (!usable_[t]) {
      ++degenerate_tets_;
      continue;
    }
    origin_[t] = p0;
    inverse_[t] = edges.inverse();
    for (int c = 0; c < 4; ++c) {
      lo = lo.cwiseMin(positions_mm[tet[c]]);
      hi = hi.cwiseMax(positions_mm[tet[c]]);
    }
    mean_extent += edges.cwiseAbs().rowwise().maxCoeff().sum() / 3.0;
  }
  const int usable_count = static_cast<int>(tet_count) - degenerate_tets_;
  if (usable_count == 0) {
    bins_ = Eigen::Vector3i::Ones();
    bin_start_.assign(2, 0);
    bin_tets_.clear();
    return;
  }
  mean_extent /= usable_count;

  // About one bin per tet edge length: few tets per bin, few bins per tet.
  const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-9);
  bins_min_ = lo;
  for (int a = 0; a < 3; ++a) {
    bins_[a] = std::clamp(static_cast<int>(std::ceil(extent[a] / mean_extent)), 1, 512);
  }
  bin_size_ = extent.cwiseQuotient(bins_.cast<double>());

  const std::size_t bin_count = static_cast<std::size_t>(bins_.prod());
  bin_start_.assign(bin_count + 1, 0);
  const auto bin_coord = [&](double v, int axis) {
    return std::clamp(static_cast<int>((v - bins_min_[axis]) / bin_size_[axis]), 0,
                      bins_[axis] - 1);
  };
  for (std::size_t t = 0; t < tet_count; ++t) {
    if (!usable_[t]) continue;
    Eigen::Vector3d tlo = positions_mm[tets_[t][0]], thi = tlo;
    for (int c = 1; c < 4; ++c) {
      tlo = tlo.cwiseMin(positions_mm[tets_[t][c]]);
      thi = thi.cwiseMax(positions_mm[tets_[t][c]]);
    }
    auto& r = tet_bin_range_[t];
    for (int a = 0; a < 3; ++a) {
      r[a] = bin_coord(tlo[a], a);
      r[a + 3] = bin_coord(thi[a], a);
    }
    for (int k = r[2]; k <= r[5]; ++k)
      for (int j = r[1]; j <= r[4]; ++j)
        for (int i = r[0]; i <= r[3]; ++i) ++bin_start_[1 + i + bins_.x() * (j + bins_.y() * k)];
  }
  for (std::size_t b = 0; b < bin_count; ++b) bin_start_[b + 1] += bin_start_[b];
  bin_tets_.resize(static_cast<std::size_t>(bin_start_[bin_count]));
  std::vector<std::int32_t>& fill = scratch_fill_;
  fill.assign(bin_start_.begin(), bin_start_.end() - 1);
  for (std::size_t t = 0; t < tet_count; ++t) {
    if (!usable_[t]) continue;
    const auto& r = tet_bin_range_[t];
    for (int k = r[2]; k <= r[5]; ++k)
      for (int j = r[1]; j <= r[4]; ++j)
        for (int i = r[0]; i <= r[3]; ++i)
          bin_tets_[fill[i + bins_.x() * (j + bins_.y() * k)]++] = static_cast<std::int32_t>(t);
  }
}

bool TetLocator::bin_of(const Eigen::Vector3d& p, Eigen::Vector3i& bin) const {
  for (int a = 0; a < 3; ++a) {
    const double f = (p[a] - bins_min_[a]) / bin_size_[a];
    if (!(f >= -1e-9 && f <= bins_[a] + 1e-9)) return false;
    bin[a] = std::clamp(static_cast<int>(f), 0, bins_[a] - 1);
  }
  return true;
}

std::optional<TetLocation> TetLocator::locate(const Eigen::Vector3d& p_mm) const {
  Eigen::Vector3i bin;
  if (bin_start_.size() < 2 || !bin_of(p_mm, bin)) return std::nullopt;
  const int b = bin.x() + bins_.x() * (bin.y() + bins_.y() * bin.z());
  for (int n = bin_start_[b]; n < bin_start_[b + 1]; ++n) {
    const std::int32_t t = bin_tets_[n];
    const Eigen::Vector3d l = inverse_[t] * (p_mm - origin_[t]);
    const double l0 = 1.0 - l.sum();
    if (l.minCoeff() >= -kBarycentricTolerance && l0 >= -kBarycentricTolerance) {
      return TetLocation{t, Eigen::Vector4d(l0, l.x(), l.y(), l.z())};
    }
  }
  return std::nullopt;
}

}  // namespace ultrasim::geometry
