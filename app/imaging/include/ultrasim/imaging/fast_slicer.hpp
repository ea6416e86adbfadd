#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/bscan.hpp"
#include "ultrasim/imaging/settings.hpp"
#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging {

class GridRowRuns;
namespace slicer_detail {
struct VoxelGrid;
// Samples one row span of a cut (app/imaging/src/trilinear_span.hpp).
using SpanKernel = void (*)(const VoxelGrid& grid, const double* index_at_col0, const double* step,
                            int first, int last, std::uint8_t* out);
}  // namespace slicer_detail

// B-scan of the deformed tissue by cutting the mesh with the image plane (method (c)); the same
// image as slice_deformed_reference (±1 grey level from rounding; background on the same pixels).
//
// Per frame, prepare() finds the tets the plane cuts (deformed positions) and gives each its
// barycentric coordinates and its rest position's volume index as affine functions of the pixel
// coordinates. The cut of a tet is the convex polygon (triangle or quad) where its four
// barycentric coordinates are all >= 0, so slice_rows() scan-converts it row by row: each
// coordinate bounds the row's span from one side, and the pixels of the span interpolate the rest
// position and sample the volume trilinearly. Like the reference (geometry::TetLocator), a pixel
// belongs to a tet when all four coordinates are >= -1e-9: pixels on an edge shared by two cuts
// are covered by both (the values agree to rounding), so no pixel of the mesh falls in a crack
// between independently rounded edges, and pixels on the mesh's own boundary count as inside,
// exactly as in the reference. Tets with non-positive volume are skipped, as TetLocator does.
//
// Rows are binned into bands of kBandRows, so slice_rows() on disjoint row ranges may run on
// several threads at once (the caller's); small chunks taken from a shared counter balance the
// work, since deep rows below the tissue cost almost nothing.
//
// Where cuts overlap (shared edges; folds of a badly deformed mesh) the lowest-numbered tet wins,
// as it does in the reference, whose bins list tets in mesh order; the order is fixed per row,
// so any split of the rows gives the same image.
class FastSlicer {
 public:
  static constexpr int kBandRows = 8;

  // How the pixels of a span sample the volume: four at a time with AVX2 where the CPU has it
  // (the default), or one at a time (the reference); the same bytes either way.
  enum class Sampling { kFastest, kPortable };
  // How the cut tets are found: runs of tets passed over together where their nodes show none
  // is cut (the default), or every tet looked at (the reference); the same cuts either way.
  enum class TetScan { kByRuns, kEveryTet };

  // Copies the mesh's tets and rest positions and sizes buffers for the grid: a raster grid of
  // either probe, or a linear probe's scan lines (a raster too). A convex probe's scan lines fan
  // out and throw std::invalid_argument: acquire those with slice_deformed_reference. Allocates.
  FastSlicer(const geometry::TetMesh& mesh, const BscanGrid& grid,
             Sampling sampling = Sampling::kFastest, TetScan scan = TetScan::kByRuns);
  ~FastSlicer();
  FastSlicer(FastSlicer&&) noexcept;
  FastSlicer& operator=(FastSlicer&&) noexcept;

  // Switches to another image grid (probe, depth or size changed), with the constructor's
  // conditions. Allocates; not per frame.
  void set_grid(const BscanGrid& grid);

  // Per-frame setup: which tets the plane of `pose` cuts at the deformed positions
  // (node_count entries, mm) and their pixel→barycentric and pixel→volume-index maps. `volume`
  // is kept by reference and must stay alive and unchanged until this frame's slice_rows() calls
  // are done (and hold fewer than 2^31 voxels). The probe axes' columns 0 and 2 must be
  // independent (a rotation in practice); std::invalid_argument for a wrong node count.
  // One thread; not concurrently with slice_rows(). Allocates only when a frame cuts more tets
  // than any earlier frame (buffers keep their high-water size), never otherwise.
  void prepare(const Volume<std::uint8_t>& volume,
               std::span<const Eigen::Vector3d> deformed_positions_mm, const ProbePose& pose);

  // prepare() in four steps, for callers that spread the middle two over their threads:
  //   begin_prepare(...)    one thread: as prepare(), and splits the nodes and the tets into
  //                         part_count parts (1..kMaxParts); `deformed_positions_mm` must stay
  //                         alive until end_prepare() returns;
  //   classify_nodes(part)  every part in [0, part_count) once, on any threads, concurrently:
  //                         each node's side of the plane;
  //   find_cuts(part)       likewise, once every classify_nodes() has returned;
  //   end_prepare()         one thread, after every find_cuts() has returned.
  // The result is the same whatever the part count. Allocation as prepare().
  static constexpr int kMaxParts = 16;
  void begin_prepare(const Volume<std::uint8_t>& volume,
                     std::span<const Eigen::Vector3d> deformed_positions_mm, const ProbePose& pose,
                     int part_count);
  void classify_nodes(int part);
  void find_cuts(int part);
  void end_prepare();

  // Writes rows [row_begin, row_end) of the image; `out` is the whole image, width_px ×
  // height_px bytes, row-major, and only those rows are touched. Pixels outside the sector (convex
  // grids), the deformed mesh or the volume get settings.background_grey; the others the volume
  // echo at the pixel's rest position, as recorded (display controls come after, in
  // DisplayMapping; settings.width_px/height_px are ignored: the grid sets the size). Safe to call
  // from several threads at once on disjoint row ranges after prepare(). Does not allocate;
  // std::invalid_argument when `out` is smaller than the image.
  void slice_rows(const BscanSettings& settings, int row_begin, int row_end,
                  std::span<std::uint8_t> out) const;

  // The whole image on the calling thread: slice_rows(settings, 0, height_px(), out).
  void slice(const BscanSettings& settings, std::span<std::uint8_t> out) const {
    slice_rows(settings, 0, height_px_, out);
  }

  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  // Tets cut by the plane inside the image at the last prepare() (a cost figure).
  int cut_tet_count() const { return cut_count_; }

 private:
  // A bound on the columns of one row of a cut, affine in the row: at_row0 + row · per_row.
  struct ColumnBound {
    double at_row0, per_row;
  };
  // One tet's cut. Each barycentric coordinate is affine in the pixel coordinates, so
  // "coordinate >= -tolerance" bounds every row's columns from one side; likewise "voxel index
  // within the volume" for cuts that reach the volume's edge. Unused bounds are open.
  struct CutTet {
    std::array<ColumnBound, 4> first_in_tet, last_in_tet;
    std::array<ColumnBound, 3> first_in_volume, last_in_volume;
    Eigen::Vector3d index_at_origin, index_per_col, index_per_row;  // volume index of rest pos
    int row_min, row_max;  // rows the cut may reach, clamped to the image
    bool clip_to_volume;   // the rest tet reaches the volume's edge: bound spans by it too
    int volume_row_min, volume_row_max;  // with clipping: rows that can reach into the volume
  };
  void draw_cut_rows(const CutTet& cut, int row_first, int row_last,
                     const slicer_detail::VoxelGrid& grid, std::uint8_t background,
                     std::span<std::uint8_t> out) const;
  // Tet t's cut, appended to `cuts` where the plane cuts it inside the image.
  void add_cut(std::size_t t, std::vector<CutTet>& cuts) const;
  // Whether run `run` of tets may hold a tet the plane cuts (its nodes' sides, or true for a run
  // without a node list).
  bool run_may_be_cut(std::size_t run) const;

  std::vector<geometry::Tet> tets_;
  std::vector<Eigen::Vector3d> rest_mm_;
  // The tets in runs of kTetsPerRun in mesh order, and the nodes each run uses (each once): a run
  // none of whose nodes lies on the plane or on both sides of it holds no cut tet. A mesh in grid
  // order has ~48 nodes a run, 192 bytes against the run's 1 KB of tets, and most runs lie
  // away from the plane. A run with more nodes than tets (a mesh in no spatial order), or every
  // run with TetScan::kEveryTet, keeps no list: its tets are looked at one by one.
  static constexpr std::size_t kTetsPerRun = 64;
  std::vector<std::int32_t> run_node_start_;  // per run + 1: offset into run_nodes_; none: empty
  std::vector<std::int32_t> run_nodes_;
  BscanGrid grid_;
  int width_px_ = 0;
  int height_px_ = 0;
  std::unique_ptr<GridRowRuns> row_runs_;
  // The span kernels (by Sampling): the samples of a span inside the volume, and of one that
  // may reach its edge.
  slicer_detail::SpanKernel sample_inside_ = nullptr;
  slicer_detail::SpanKernel sample_clamped_ = nullptr;

  // Per volume: the geometry last seen, and per tet whether its rest position stays clear of the
  // volume's edge (its pixels need no clipping).
  struct VolumeGeometry {
    Eigen::Vector3i size = Eigen::Vector3i::Zero();
    Eigen::Vector3d spacing_mm = Eigen::Vector3d::Zero(), origin_mm = Eigen::Vector3d::Zero();
    Eigen::Matrix3d direction = Eigen::Matrix3d::Zero();
    static VolumeGeometry of(const Volume<std::uint8_t>& v) {
      return {v.size(), v.spacing_mm(), v.origin_mm(), v.direction()};
    }
    bool operator==(const VolumeGeometry&) const = default;
  };
  VolumeGeometry volume_geometry_;
  std::vector<std::uint8_t> tet_inside_volume_;

  // Per frame.
  struct Frame;
  std::unique_ptr<Frame> frame_;
  const Volume<std::uint8_t>* volume_ = nullptr;
  std::span<const Eigen::Vector3d> positions_mm_;  // deformed, between begin and end_prepare
  int part_count_ = 1;
  std::vector<double> node_distance_mm_;  // signed distance of each deformed node to the plane
  std::vector<std::uint8_t> node_side_;   // and its side as bits (above, below, on)
  std::array<std::vector<CutTet>, kMaxParts> part_cuts_;  // cuts found by each part, tet order
  int cut_count_ = 0;
  std::vector<std::int32_t> band_start_;  // per band + 1: offset into band_cuts_
  std::vector<const CutTet*> band_cuts_;  // cuts grouped by band, in mesh order
  std::vector<std::int32_t> band_fill_;   // scratch cursor per band while binning
};

}  // namespace ultrasim::imaging
