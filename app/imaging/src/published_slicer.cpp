#include "ultrasim/imaging/published_slicer.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "grid_row_runs.hpp"
#include "pixel_plane.hpp"
#include "ultrasim/geometry/tet_edges.hpp"

namespace ultrasim::imaging {

namespace {

// geometry::TetLocator's tolerance, so a pixel is inside the mesh exactly when the reference says.
constexpr double kBarycentricTolerance = 1e-9;
// Slack on "the bounding box crosses the plane" and on a tet's projected rows, so tets that touch
// the plane or a region within rounding stay listed: the reference admits their pixels through
// its tolerance.
constexpr double kCrossingSlackMm = 1e-6;
constexpr double kRowMarginPx = 1e-3;

}  // namespace

// One row being walked: where its pixels go and how they are shaded.
struct PublishedSlicer::RowContext {
  int row;
  std::span<const std::int32_t> region_tets;
  std::span<std::uint8_t> out;  // the row's pixels
};

PublishedSlicer::PublishedSlicer(const geometry::TetMesh& mesh, const BscanGrid& grid,
                                 int region_count)
    : tets_(mesh.tets),
      rest_mm_(mesh.rest_positions_mm),
      grid_(grid),
      requested_region_count_(region_count),
      row_runs_(std::make_unique<GridRowRuns>()) {
  set_grid(grid);
}

PublishedSlicer::~PublishedSlicer() = default;
PublishedSlicer::PublishedSlicer(PublishedSlicer&&) noexcept = default;
PublishedSlicer& PublishedSlicer::operator=(PublishedSlicer&&) noexcept = default;

void PublishedSlicer::set_grid(const BscanGrid& grid) {
  // A convex probe's scan lines fan out: their samples are no affine image of the pixel grid,
  // which both the spans here and the interpolation along rows rely on.
  if (grid.layout() == BscanGrid::Layout::kScanLines && grid.probe().kind == ProbeKind::kConvex) {
    throw std::invalid_argument(
        "PublishedSlicer: convex scan-line grids need the reference slicer");
  }
  grid_ = grid;
  width_px_ = grid.width_px();
  height_px_ = grid.height_px();
  row_runs_->assign(grid);
  set_region_count(requested_region_count_);
}

void PublishedSlicer::set_region_count(int region_count) {
  if (region_count < 1) throw std::invalid_argument("PublishedSlicer: region count must be >= 1");
  requested_region_count_ = region_count;
  region_count_ = std::min(region_count, height_px_);
  // Region m holds rows [m·H/M, (m+1)·H/M).
  region_of_row_.resize(static_cast<std::size_t>(height_px_));
  for (int m = 0; m < region_count_; ++m) {
    const int first = static_cast<int>(static_cast<long long>(m) * height_px_ / region_count_);
    const int end = static_cast<int>(static_cast<long long>(m + 1) * height_px_ / region_count_);
    for (int row = first; row < end; ++row) region_of_row_[row] = m;
  }
  region_start_.assign(static_cast<std::size_t>(region_count_) + 1, 0);
  region_fill_.assign(static_cast<std::size_t>(region_count_), 0);
  crossing_.clear();
  crossing_regions_.clear();
  region_tets_.clear();
}

void PublishedSlicer::prepare(const Volume<std::uint8_t>& volume,
                              std::span<const Eigen::Vector3d> deformed_positions_mm,
                              const ProbePose& pose) {
  if (deformed_positions_mm.size() != rest_mm_.size()) {
    throw std::invalid_argument("PublishedSlicer::prepare: one deformed position per mesh node");
  }
  const auto& x = deformed_positions_mm;
  volume_ = &volume;
  pose_ = pose;
  const PixelPlane plane = PixelPlane::of(grid_, pose);

  crossing_.clear();
  crossing_regions_.clear();
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    const geometry::Tet& tet = tets_[t];
    Eigen::Vector3d lo = x[tet[0]], hi = lo;
    for (int c = 1; c < 4; ++c) {
      lo = lo.cwiseMin(x[tet[c]]);
      hi = hi.cwiseMax(x[tet[c]]);
    }
    // The box crosses the plane when its centre is no farther from it than the box reaches.
    const double centre_mm = plane.unit_normal.dot(0.5 * (lo + hi) - plane.origin_mm);
    const double reach_mm = plane.unit_normal.cwiseAbs().dot(0.5 * (hi - lo));
    if (!(std::abs(centre_mm) <= reach_mm + kCrossingSlackMm)) continue;

    // TetLocator's rule for a usable tet, to the bit, so both skip the same tets.
    const Eigen::Vector3d& p0 = x[tet[0]];
    const Eigen::Matrix3d edges = geometry::tet_edge_matrix(x, tet);
    if (!geometry::usable_tet(edges)) continue;

    // The cut lies inside the tet's shadow on the plane, so the projected nodes bound its pixels.
    constexpr double kInf = std::numeric_limits<double>::infinity();
    Eigen::Vector2d px_lo(kInf, kInf), px_hi(-kInf, -kInf);
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d px = plane.pixel_of(x[tet[c]]);
      px_lo = px_lo.cwiseMin(px);
      px_hi = px_hi.cwiseMax(px);
    }
    if (px_hi.x() < -kRowMarginPx || px_lo.x() > width_px_ - 1 + kRowMarginPx) continue;
    const int row_min = std::max(0, static_cast<int>(std::ceil(px_lo.y() - kRowMarginPx)));
    const int row_max =
        std::min(height_px_ - 1, static_cast<int>(std::floor(px_hi.y() + kRowMarginPx)));
    if (row_min > row_max) continue;
    crossing_.push_back({edges.inverse(), p0, static_cast<std::int32_t>(t)});
    crossing_regions_.push_back(region_of_row_[row_min]);
    crossing_regions_.push_back(region_of_row_[row_max]);
  }

  // Region lists by counting sort, crossing tets in mesh order inside each.
  std::fill(region_start_.begin(), region_start_.end(), 0);
  for (std::size_t i = 0; i < crossing_.size(); ++i) {
    for (int m = crossing_regions_[2 * i]; m <= crossing_regions_[2 * i + 1]; ++m)
      ++region_start_[m + 1];
  }
  for (int m = 0; m < region_count_; ++m) region_start_[m + 1] += region_start_[m];
  region_tets_.resize(static_cast<std::size_t>(region_start_.back()));
  std::copy(region_start_.begin(), region_start_.end() - 1, region_fill_.begin());
  for (std::size_t i = 0; i < crossing_.size(); ++i) {
    for (int m = crossing_regions_[2 * i]; m <= crossing_regions_[2 * i + 1]; ++m) {
      region_tets_[region_fill_[m]++] = static_cast<std::int32_t>(i);
    }
  }
}

void PublishedSlicer::slice_rows(const BscanSettings& settings, int row_begin, int row_end,
                                 std::span<std::uint8_t> out) const {
  if (out.size() < static_cast<std::size_t>(width_px_) * height_px_) {
    throw std::invalid_argument("PublishedSlicer::slice_rows: image smaller than the grid");
  }
  row_begin = std::max(row_begin, 0);
  row_end = std::min(row_end, height_px_);
  for (int row = row_begin; row < row_end; ++row) {
    const auto row_out = out.subspan(static_cast<std::size_t>(row) * width_px_, width_px_);
    std::ranges::fill(row_out, static_cast<std::uint8_t>(settings.background_grey));
    if (volume_ == nullptr) continue;
    const int m = region_of_row_[row];
    const RowContext context{
        row,
        std::span<const std::int32_t>(region_tets_)
            .subspan(region_start_[m], region_start_[m + 1] - region_start_[m]),
        row_out};
    for (const PixelRun& run : row_runs_->row(row)) {
      const int a = run.col_begin, z = run.col_end - 1;
      const Location at_a = locate(context, a);
      walk(context, a, at_a, z, z == a ? at_a : locate(context, z));
    }
  }
}

PublishedSlicer::Location PublishedSlicer::locate(const RowContext& row, int col) const {
  // The pixel's position exactly as the reference computes it, so barycentric coordinates agree
  // to the bit in the same tet.
  const Eigen::Vector3d p = pose_.to_patient(*grid_.pixel_to_plane_mm(col, row.row));
  for (const std::int32_t i : row.region_tets) {
    const CrossingTet& crossing = crossing_[i];
    const Eigen::Vector3d l = crossing.inverse * (p - crossing.origin);
    const double l0 = 1.0 - l.sum();
    if (l.minCoeff() >= -kBarycentricTolerance && l0 >= -kBarycentricTolerance) {
      const geometry::Tet& tet = tets_[crossing.tet];
      const Eigen::Vector4d barycentric(l0, l.x(), l.y(), l.z());
      Location location;
      location.crossing = i;
      for (int c = 0; c < 4; ++c) location.rest_mm += barycentric[c] * rest_mm_[tet[c]];
      return location;
    }
  }
  return {};
}

void PublishedSlicer::walk(const RowContext& row, int a, const Location& at_a, int z,
                           const Location& at_z) const {
  if (at_a.crossing >= 0 && at_a.crossing == at_z.crossing) {
    // Both ends in one tet: the rest position is affine along the segment between them.
    shade(row, a, at_a.rest_mm);
    const Eigen::Vector3d step = (at_z.rest_mm - at_a.rest_mm) / std::max(z - a, 1);
    for (int col = a + 1; col < z; ++col) shade(row, col, at_a.rest_mm + (col - a) * step);
    if (z != a) shade(row, z, at_z.rest_mm);
    return;
  }
  if (z - a <= 1) {
    if (at_a.crossing >= 0) shade(row, a, at_a.rest_mm);
    if (z != a && at_z.crossing >= 0) shade(row, z, at_z.rest_mm);
    return;
  }
  const int m = a + (z - a) / 2;  // a < m < z
  const Location at_m_minus_1 = m - 1 == a ? at_a : locate(row, m - 1);
  const Location at_m = locate(row, m);
  walk(row, a, at_a, m - 1, at_m_minus_1);
  walk(row, m, at_m, z, at_z);
}

void PublishedSlicer::shade(const RowContext& row, int col, const Eigen::Vector3d& rest_mm) const {
  // As slice_deformed_reference: rest positions outside the volume keep the background.
  const float echo = volume_->sample_trilinear(rest_mm, -1.0f);
  if (echo < 0) return;
  row.out[col] = echo_to_grey(echo);
}

}  // namespace ultrasim::imaging
