#include "ultrasim/imaging/fast_slicer.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "grid_row_runs.hpp"
#include "pixel_plane.hpp"
#include "trilinear_span.hpp"
#include "ultrasim/geometry/tet_edges.hpp"

namespace ultrasim::imaging {

namespace {

// geometry::TetLocator's tolerance: a point is in a tet when its barycentric coordinates are all
// >= -1e-9. Using the same one puts the same pixels inside the mesh.
constexpr double kBarycentricTolerance = 1e-9;
// Volume::sample_trilinear's tolerance on voxel indices at the volume's edge.
constexpr double kVolumeEdge = 1e-9;
// Nodes this close to the plane count as on it, so a tet that only touches the plane (within
// rounding) is still cut: the reference admits its pixels through its tolerance.
constexpr double kOnPlaneMm = 1e-6;
// Rows a cut may reach, widened by this much: the barycentric tolerance lets a cut reach a hair
// beyond its exact polygon. Extra rows cost one empty span each.
constexpr double kRowMarginPx = 1e-3;
// A rest tet this far inside the volume (in voxels) needs no clipping against the volume's edge.
constexpr double kInteriorMarginVoxels = 1e-6;
// Bits of a node's side of the plane.
constexpr std::uint8_t kAbove = 1, kBelow = 2, kOnPlane = 4;
// An unused column bound; any real bound is tighter.
constexpr double kOpen = 1e300;

// value(col, row) = at_origin + col · per_col + row · per_row, required >= min_value.
struct Constraint {
  double at_origin, per_col, per_row, min_value;
};

// Turns a constraint into a bound on the first or the last column of each row, affine in the row
// (col >= or <= (min_value - at_origin - row · per_row) / per_col), or, where it does not depend
// on the column, into a bound on the rows. `Bound` is {at_row0, per_row}; `next_first` and
// `next_last` index the next free slot of each side.
template <typename Bound, std::size_t N>
void add_bound(const Constraint& c, std::array<Bound, N>& first, std::size_t& next_first,
               std::array<Bound, N>& last, std::size_t& next_last, int& row_min, int& row_max) {
  // A coefficient this small moves the value by nothing across the image; dividing by it could
  // overflow to inf - inf = NaN in the bound.
  constexpr double kNegligible = 1e-200;
  if (std::abs(c.per_col) > kNegligible) {
    const Bound bound{(c.min_value - c.at_origin) / c.per_col, -c.per_row / c.per_col};
    if (c.per_col > 0) {
      first[next_first++] = bound;
    } else {
      last[next_last++] = bound;
    }
    return;
  }
  // Rows where at_origin + row · per_row >= min_value; clamped in double before converting.
  if (std::abs(c.per_row) <= kNegligible) {
    if (!(c.at_origin >= c.min_value)) row_max = -1;
    return;
  }
  const double edge = std::clamp((c.min_value - c.at_origin) / c.per_row, -1.0, 1e9);
  if (c.per_row > 0) {
    row_min = std::max(row_min, static_cast<int>(std::ceil(edge)));
  } else {
    row_max = std::min(row_max, static_cast<int>(std::floor(edge)));
  }
}

}  // namespace

// The image plane and volume mapping of the frame being prepared.
struct FastSlicer::Frame {
  PixelPlane plane;
  Eigen::Matrix3d world_to_index = Eigen::Matrix3d::Identity();
  Eigen::Vector3d index_max = Eigen::Vector3d::Zero();
};

FastSlicer::FastSlicer(const geometry::TetMesh& mesh, const BscanGrid& grid, Sampling sampling,
                       TetScan scan)
    : tets_(mesh.tets),
      rest_mm_(mesh.rest_positions_mm),
      grid_(grid),
      row_runs_(std::make_unique<GridRowRuns>()),
      tet_inside_volume_(mesh.tets.size()),
      frame_(std::make_unique<Frame>()),
      node_distance_mm_(mesh.rest_positions_mm.size()),
      node_side_(mesh.rest_positions_mm.size()) {
  const slicer_detail::SpanKernels kernels = sampling == Sampling::kPortable
                                                 ? slicer_detail::portable_span_kernels()
                                                 : slicer_detail::fastest_span_kernels();
  sample_inside_ = kernels.inside;
  sample_clamped_ = kernels.clamped;
  const std::size_t runs = (tets_.size() + kTetsPerRun - 1) / kTetsPerRun;
  run_node_start_.reserve(runs + 1);
  run_node_start_.push_back(0);
  std::vector<std::int32_t> nodes;
  for (std::size_t run = 0; run < runs; ++run) {
    nodes.clear();
    for (std::size_t t = run * kTetsPerRun; t < std::min(tets_.size(), (run + 1) * kTetsPerRun);
         ++t) {
      nodes.insert(nodes.end(), tets_[t].begin(), tets_[t].end());
    }
    std::ranges::sort(nodes);
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    if (scan == TetScan::kByRuns && nodes.size() <= kTetsPerRun) {
      run_nodes_.insert(run_nodes_.end(), nodes.begin(), nodes.end());
    }
    run_node_start_.push_back(static_cast<std::int32_t>(run_nodes_.size()));
  }
  set_grid(grid);
}

FastSlicer::~FastSlicer() = default;
FastSlicer::FastSlicer(FastSlicer&&) noexcept = default;
FastSlicer& FastSlicer::operator=(FastSlicer&&) noexcept = default;

void FastSlicer::set_grid(const BscanGrid& grid) {
  // A convex probe's scan lines fan out: their samples are no affine image of the pixel grid,
  // which both the spans here and the interpolation along rows rely on.
  if (grid.layout() == BscanGrid::Layout::kScanLines && grid.probe().kind == ProbeKind::kConvex) {
    throw std::invalid_argument("FastSlicer: convex scan-line grids need the reference slicer");
  }
  grid_ = grid;
  width_px_ = grid.width_px();
  height_px_ = grid.height_px();
  row_runs_->assign(grid);
  const std::size_t bands = static_cast<std::size_t>((height_px_ + kBandRows - 1) / kBandRows);
  band_start_.assign(bands + 1, 0);
  band_fill_.assign(bands, 0);
  for (auto& cuts : part_cuts_) cuts.clear();
  cut_count_ = 0;
  band_cuts_.clear();
}

void FastSlicer::prepare(const Volume<std::uint8_t>& volume,
                         std::span<const Eigen::Vector3d> deformed_positions_mm,
                         const ProbePose& pose) {
  begin_prepare(volume, deformed_positions_mm, pose, 1);
  classify_nodes(0);
  find_cuts(0);
  end_prepare();
}

void FastSlicer::begin_prepare(const Volume<std::uint8_t>& volume,
                               std::span<const Eigen::Vector3d> deformed_positions_mm,
                               const ProbePose& pose, int part_count) {
  if (deformed_positions_mm.size() != rest_mm_.size()) {
    throw std::invalid_argument("FastSlicer: one deformed position per mesh node");
  }
  if (part_count < 1 || part_count > kMaxParts) {
    throw std::invalid_argument("FastSlicer: part count out of range");
  }
  // The sampling loop indexes voxels with int offsets (fewer instructions per pixel).
  if (volume.voxel_count() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::invalid_argument("FastSlicer: volumes of 2^31 voxels or more are not supported");
  }
  volume_ = &volume;
  positions_mm_ = deformed_positions_mm;
  part_count_ = part_count;
  frame_->plane = PixelPlane::of(grid_, pose);
  frame_->world_to_index = (volume.direction() * volume.spacing_mm().asDiagonal()).inverse();
  frame_->index_max = volume.size().cast<double>().array() - 1.0;
  const Eigen::Matrix3d& world_to_index = frame_->world_to_index;
  const Eigen::Vector3d& index_max = frame_->index_max;
  if (!(volume_geometry_ == VolumeGeometry::of(volume))) {
    // A new volume (the first frame, or another case): which rest tets stay clear of its edge,
    // so that their pixels need no clipping. Once per volume, not per frame.
    volume_geometry_ = VolumeGeometry::of(volume);
    for (std::size_t t = 0; t < tets_.size(); ++t) {
      bool inside = true;
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector3d index = world_to_index * (rest_mm_[tets_[t][c]] - volume.origin_mm());
        inside = inside && (index.array() >= kInteriorMarginVoxels).all() &&
                 (index.array() <= index_max.array() - kInteriorMarginVoxels).all();
      }
      tet_inside_volume_[t] = inside;
    }
  }
}

void FastSlicer::classify_nodes(int part) {
  const PixelPlane& plane = frame_->plane;
  const auto& x = positions_mm_;
  // Which side of the plane each node lies on, as bits, so that a tet's four nodes (and a run's
  // nodes) are classified with ORs: most tets are nowhere near the plane. The large case's 67,000
  // nodes took ~8 % of its B-scan on one thread.
  const std::size_t n_end = x.size() * (part + 1) / part_count_;
  for (std::size_t n = x.size() * part / part_count_; n < n_end; ++n) {
    const double d = plane.unit_normal.dot(x[n] - plane.origin_mm);
    node_distance_mm_[n] = d;
    node_side_[n] = static_cast<std::uint8_t>((d > 0 ? kAbove : 0) | (d < 0 ? kBelow : 0) |
                                              (std::abs(d) <= kOnPlaneMm ? kOnPlane : 0));
  }
}

void FastSlicer::find_cuts(int part) {
  std::vector<CutTet>& cuts = part_cuts_[part];
  cuts.clear();
  const std::size_t tet_count = tets_.size();
  const std::size_t t_end = tet_count * (part + 1) / part_count_;
  for (std::size_t t = tet_count * part / part_count_; t < t_end;) {
    const std::size_t run = t / kTetsPerRun;
    const std::size_t run_end = std::min(t_end, (run + 1) * kTetsPerRun);
    if (!run_may_be_cut(run)) {
      t = run_end;
      continue;
    }
    for (; t < run_end; ++t) add_cut(t, cuts);
  }
}

void FastSlicer::add_cut(std::size_t t, std::vector<CutTet>& cuts) const {
  const PixelPlane& plane = frame_->plane;
  const Eigen::Matrix3d& world_to_index = frame_->world_to_index;
  const Eigen::Vector3d& index_max = frame_->index_max;
  const Volume<std::uint8_t>& volume = *volume_;
  const auto& x = positions_mm_;
  const geometry::Tet& tet = tets_[t];
  const int sides =
      node_side_[tet[0]] | node_side_[tet[1]] | node_side_[tet[2]] | node_side_[tet[3]];
  if ((sides & (kAbove | kBelow)) != (kAbove | kBelow) && (sides & kOnPlane) == 0) return;
  const std::array<double, 4> d = {node_distance_mm_[tet[0]], node_distance_mm_[tet[1]],
                                   node_distance_mm_[tet[2]], node_distance_mm_[tet[3]]};

  // Rows the cut polygon spans: its vertices are where edges cross the plane, plus nodes on it.
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  const auto add = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector2d px = plane.pixel_of(q);
    lo = lo.cwiseMin(px);
    hi = hi.cwiseMax(px);
  };
  for (int a = 0; a < 4; ++a) {
    if (std::abs(d[a]) <= kOnPlaneMm) add(x[tet[a]] - d[a] * plane.unit_normal);
    for (int b = a + 1; b < 4; ++b) {
      if ((d[a] < 0 && d[b] > 0) || (d[a] > 0 && d[b] < 0)) {
        add(x[tet[a]] + (x[tet[b]] - x[tet[a]]) * (d[a] / (d[a] - d[b])));
      }
    }
  }
  if (hi.x() < -kRowMarginPx || lo.x() > width_px_ - 1 + kRowMarginPx || hi.y() < -kRowMarginPx ||
      lo.y() > height_px_ - 1 + kRowMarginPx) {
    return;
  }
  CutTet cut;
  cut.row_min = std::max(0, static_cast<int>(std::ceil(lo.y() - kRowMarginPx)));
  cut.row_max = std::min(height_px_ - 1, static_cast<int>(std::floor(hi.y() + kRowMarginPx)));
  if (cut.row_min > cut.row_max) return;

  // TetLocator's rule for a usable tet, to the bit, so both skip the same tets.
  const Eigen::Vector3d& p0 = x[tet[0]];
  const Eigen::Matrix3d edges = geometry::tet_edge_matrix(x, tet);
  if (!geometry::usable_tet(edges)) return;

  // Barycentric coordinates (1..3 from the edge matrix's inverse, 0 as the rest) of the pixel
  // centres: affine in (col, row) because the plane is.
  const Eigen::Matrix3d inverse = edges.inverse();
  const Eigen::Vector3d at_origin = inverse * (plane.origin_mm - p0);
  const Eigen::Vector3d per_col = inverse * plane.per_col_mm;
  const Eigen::Vector3d per_row = inverse * plane.per_row_mm;
  cut.first_in_tet.fill({-kOpen, 0.0});
  cut.last_in_tet.fill({kOpen, 0.0});
  std::size_t next_first = 0, next_last = 0;
  add_bound({1.0 - at_origin.sum(), -per_col.sum(), -per_row.sum(), -kBarycentricTolerance},
            cut.first_in_tet, next_first, cut.last_in_tet, next_last, cut.row_min, cut.row_max);
  for (int a = 0; a < 3; ++a) {
    add_bound({at_origin[a], per_col[a], per_row[a], -kBarycentricTolerance}, cut.first_in_tet,
              next_first, cut.last_in_tet, next_last, cut.row_min, cut.row_max);
  }
  if (cut.row_min > cut.row_max) return;

  // Rest position = r0 + [r1-r0 r2-r0 r3-r0] · (barycentric 1..3), then to voxel indices.
  const Eigen::Vector3d& r0 = rest_mm_[tet[0]];
  const Eigen::Matrix3d to_index = world_to_index * geometry::tet_edge_matrix(rest_mm_, tet);
  cut.index_at_origin = world_to_index * (r0 - volume.origin_mm()) + to_index * at_origin;
  cut.index_per_col = to_index * per_col;
  cut.index_per_row = to_index * per_row;

  cut.clip_to_volume = !tet_inside_volume_[t];
  cut.first_in_volume.fill({-kOpen, 0.0});
  cut.last_in_volume.fill({kOpen, 0.0});
  cut.volume_row_min = 0;
  cut.volume_row_max = height_px_ - 1;
  if (cut.clip_to_volume) {
    // Voxel index a within [-1e-9, size - 1 + 1e-9], as Volume::sample_trilinear wants it. A
    // row the volume misses entirely keeps its pixels in the tet, as background.
    next_first = next_last = 0;
    for (int a = 0; a < 3; ++a) {
      add_bound({cut.index_at_origin[a], cut.index_per_col[a], cut.index_per_row[a], -kVolumeEdge},
                cut.first_in_volume, next_first, cut.last_in_volume, next_last, cut.volume_row_min,
                cut.volume_row_max);
      add_bound({-cut.index_at_origin[a], -cut.index_per_col[a], -cut.index_per_row[a],
                 -(index_max[a] + kVolumeEdge)},
                cut.first_in_volume, next_first, cut.last_in_volume, next_last, cut.volume_row_min,
                cut.volume_row_max);
    }
  }
  cuts.push_back(cut);
}

bool FastSlicer::run_may_be_cut(std::size_t run) const {
  const std::int32_t begin = run_node_start_[run], end = run_node_start_[run + 1];
  if (begin == end) return true;
  std::uint8_t sides = 0;
  for (std::int32_t i = begin; i < end; ++i) sides |= node_side_[run_nodes_[i]];
  // find_cuts' test for one tet, on the run's nodes together: a run it fails, each tet fails.
  return (sides & (kAbove | kBelow)) == (kAbove | kBelow) || (sides & kOnPlane) != 0;
}

void FastSlicer::end_prepare() {
  // Bin the cuts by bands of rows (counting sort), keeping mesh order inside each band: parts in
  // order, each in tet order.
  const auto parts = std::span(part_cuts_).first(static_cast<std::size_t>(part_count_));
  std::fill(band_start_.begin(), band_start_.end(), 0);
  cut_count_ = 0;
  for (const std::vector<CutTet>& cuts : parts) {
    cut_count_ += static_cast<int>(cuts.size());
    for (const CutTet& cut : cuts) {
      for (int b = cut.row_min / kBandRows; b <= cut.row_max / kBandRows; ++b) ++band_start_[b + 1];
    }
  }
  for (std::size_t b = 0; b + 1 < band_start_.size(); ++b) band_start_[b + 1] += band_start_[b];
  band_cuts_.resize(static_cast<std::size_t>(band_start_.back()));
  std::copy(band_start_.begin(), band_start_.end() - 1, band_fill_.begin());
  for (const std::vector<CutTet>& cuts : parts) {
    for (const CutTet& cut : cuts) {
      for (int b = cut.row_min / kBandRows; b <= cut.row_max / kBandRows; ++b) {
        band_cuts_[band_fill_[b]++] = &cut;
      }
    }
  }
}

void FastSlicer::slice_rows(const BscanSettings& settings, int row_begin, int row_end,
                            std::span<std::uint8_t> out) const {
  if (out.size() < static_cast<std::size_t>(width_px_) * height_px_) {
    throw std::invalid_argument("FastSlicer::slice_rows: image smaller than the grid");
  }
  row_begin = std::max(row_begin, 0);
  row_end = std::min(row_end, height_px_);
  if (row_begin >= row_end) return;
  const auto row_span = [&](int row) {
    return out.subspan(static_cast<std::size_t>(row) * width_px_, width_px_);
  };
  for (int row = row_begin; row < row_end; ++row) {
    std::ranges::fill(row_span(row), static_cast<std::uint8_t>(settings.background_grey));
  }
  if (volume_ == nullptr) return;

  const slicer_detail::VoxelGrid grid = slicer_detail::voxel_grid_of(*volume_);
  const auto background = static_cast<std::uint8_t>(settings.background_grey);

  for (int band = row_begin / kBandRows; band <= (row_end - 1) / kBandRows; ++band) {
    const int band_first = std::max(row_begin, band * kBandRows);
    const int band_last = std::min(row_end, (band + 1) * kBandRows) - 1;
    // Backwards, so that where cuts overlap the lowest-numbered tet is drawn last and wins: the
    // reference returns the first tet of its bin that holds the pixel, and its bins list tets in
    // mesh order. Overlaps are pixels on shared edges (same value either way) and folds of a
    // mesh whose tets overlap without inverting.
    for (int i = band_start_[band + 1] - 1; i >= band_start_[band]; --i) {
      const CutTet& cut = *band_cuts_[i];
      draw_cut_rows(cut, std::max(band_first, cut.row_min), std::min(band_last, cut.row_max), grid,
                    background, out);
    }
  }
}

namespace {

// The first and last whole column in [lo, hi] after clamping both to [0, width - 1]; first >
// last when there is none. Integer truncation with a correction instead of std::ceil/floor:
// without SSE4.1 those are library-style emulations, and this runs once per row of every cut.
// The comparisons are written so that a NaN bound still converts to a column inside the image.
inline void whole_columns(double lo, double hi, int width, int& first, int& last) {
  lo = lo > 0.0 ? std::min(lo, static_cast<double>(width)) : 0.0;
  hi = hi < width - 1.0 ? std::max(hi, -1.0) : width - 1.0;
  first = static_cast<int>(lo);
  first += first < lo;
  last = static_cast<int>(hi);
  last -= last > hi;
}

template <std::size_t N, typename Bound>
inline double tightest_first(const std::array<Bound, N>& bounds, double row) {
  double v = bounds[0].at_row0 + row * bounds[0].per_row;
  for (std::size_t k = 1; k < N; ++k) v = std::max(v, bounds[k].at_row0 + row * bounds[k].per_row);
  return v;
}
template <std::size_t N, typename Bound>
inline double tightest_last(const std::array<Bound, N>& bounds, double row) {
  double v = bounds[0].at_row0 + row * bounds[0].per_row;
  for (std::size_t k = 1; k < N; ++k) v = std::min(v, bounds[k].at_row0 + row * bounds[k].per_row);
  return v;
}

}  // namespace

void FastSlicer::draw_cut_rows(const CutTet& cut, int row_first, int row_last,
                               const slicer_detail::VoxelGrid& grid, std::uint8_t background,
                               std::span<std::uint8_t> out) const {
  const slicer_detail::SpanKernel sample = cut.clip_to_volume ? sample_clamped_ : sample_inside_;
  for (int row = row_first; row <= row_last; ++row) {
    int first, last;
    whole_columns(tightest_first(cut.first_in_tet, row), tightest_last(cut.last_in_tet, row),
                  width_px_, first, last);
    if (first > last) continue;
    std::uint8_t* row_out = out.data() + static_cast<std::size_t>(row) * width_px_;
    int sample_first = first, sample_last = last;
    if (cut.clip_to_volume) {
      if (row < cut.volume_row_min || row > cut.volume_row_max) {
        sample_first = last + 1;
      } else {
        int volume_first, volume_last;
        whole_columns(tightest_first(cut.first_in_volume, row),
                      tightest_last(cut.last_in_volume, row), width_px_, volume_first, volume_last);
        sample_first = std::max(first, volume_first);
        sample_last = std::min(last, volume_last);
      }
    }
    const Eigen::Vector3d index_at_col0 = cut.index_at_origin + row * cut.index_per_row;
    for (const PixelRun& run : row_runs_->row(row)) {
      const int run_first = std::max(first, run.col_begin);
      const int run_last = std::min(last, run.col_end - 1);
      if (run_first > run_last) continue;
      if (cut.clip_to_volume) {
        // The part of the tet whose rest position lies outside the volume shows background, as
        // in the reference, even where another tet (a fold) has drawn something.
        for (int col = run_first; col <= run_last; ++col) {
          if (col < sample_first || col > sample_last) row_out[col] = background;
        }
      }
      const int span_first = std::max(run_first, sample_first);
      const int span_last = std::min(run_last, sample_last);
      if (span_first <= span_last) {
        sample(grid, index_at_col0.data(), cut.index_per_col.data(), span_first, span_last,
               row_out);
      }
    }
  }
}

}  // namespace ultrasim::imaging
