#pragma once

#include <Eigen/Core>
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

// B-scan of the deformed tissue by the published method (method (b); the 2013 dissertation's
// §4.5, "Our approach"), kept as the baseline the faster FastSlicer is measured against. Gives
// the image of slice_deformed_reference (±1 grey level from rounding; background on the same
// pixels).
//
// prepare() lists the tets whose deformed bounding boxes cross the image plane and splits the
// image into M regions (bands of rows), each with the list of those tets whose nodes, projected
// into the image, reach its rows. slice_rows() walks each row from its left and right end pixels:
// when both lie in the same tet, the pixels between take rest positions interpolated linearly
// between the ends (exact: the map is affine inside a tet); otherwise the row is split at its
// middle pixel and each half walked the same way. A pixel is located by searching its region's
// list in order, with TetLocator's rule (all barycentric coordinates >= -1e-9; tets of
// non-positive volume left out). On a convex grid each run of in-sector pixels is walked as a row.
class PublishedSlicer {
 public:
  static constexpr int kPublishedRegionCount = 32;  // the dissertation's best M

  // Copies the mesh's tets and rest positions and sizes buffers for the grid, with region_count
  // (M >= 1) bands of rows. Grids as FastSlicer's: raster, or a linear probe's scan lines; a
  // convex probe's scan lines throw std::invalid_argument. Allocates.
  PublishedSlicer(const geometry::TetMesh& mesh, const BscanGrid& grid,
                  int region_count = kPublishedRegionCount);
  ~PublishedSlicer();
  PublishedSlicer(PublishedSlicer&&) noexcept;
  PublishedSlicer& operator=(PublishedSlicer&&) noexcept;

  // Switches the image grid, or the region count (M >= 1; an M above the image height gives one
  // row per region; std::invalid_argument below 1). Allocates; not per frame.
  void set_grid(const BscanGrid& grid);
  void set_region_count(int region_count);
  int region_count() const { return region_count_; }  // in use: at most the image height

  // Per-frame setup at the deformed positions (node_count entries, mm) and probe pose: the
  // crossing tets, their inverse edge matrices, and each region's tet list. `volume` is kept by
  // reference and must stay alive and unchanged until this frame's slice_rows() calls are done.
  // One thread; not concurrently with slice_rows(). Allocates only when a frame lists more tets
  // than any earlier frame, never otherwise.
  void prepare(const Volume<std::uint8_t>& volume,
               std::span<const Eigen::Vector3d> deformed_positions_mm, const ProbePose& pose);

  // Writes rows [row_begin, row_end) of `out` (the whole image, width_px × height_px bytes,
  // row-major); background grey outside the sector, the deformed mesh or the volume. Safe to call
  // from several threads at once on disjoint row ranges after prepare(). Does not allocate;
  // std::invalid_argument when `out` is smaller than the image.
  void slice_rows(const BscanSettings& settings, int row_begin, int row_end,
                  std::span<std::uint8_t> out) const;

  // The whole image on the calling thread.
  void slice(const BscanSettings& settings, std::span<std::uint8_t> out) const {
    slice_rows(settings, 0, height_px_, out);
  }

  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  // Tets whose bounding boxes cross the plane at the last prepare(), and the summed lengths of
  // the region lists (each crossing tet counts once per region it is listed in): cost figures.
  int crossing_tet_count() const { return static_cast<int>(crossing_.size()); }
  int region_list_entries() const { return static_cast<int>(region_tets_.size()); }

 private:
  struct CrossingTet {
    Eigen::Matrix3d inverse;  // of the deformed edge matrix [p1-p0, p2-p0, p3-p0]
    Eigen::Vector3d origin;   // deformed p0
    std::int32_t tet;         // index into tets_
  };
  struct Location {
    std::int32_t crossing = -1;  // index into crossing_, -1: outside the mesh
    Eigen::Vector3d rest_mm = Eigen::Vector3d::Zero();
  };
  struct RowContext;

  Location locate(const RowContext& row, int col) const;
  void walk(const RowContext& row, int a, const Location& at_a, int z, const Location& at_z) const;
  void shade(const RowContext& row, int col, const Eigen::Vector3d& rest_mm) const;

  std::vector<geometry::Tet> tets_;
  std::vector<Eigen::Vector3d> rest_mm_;
  BscanGrid grid_;
  int width_px_ = 0;
  int height_px_ = 0;
  int requested_region_count_ = kPublishedRegionCount;
  int region_count_ = kPublishedRegionCount;  // the requested one, at most the image height
  std::unique_ptr<GridRowRuns> row_runs_;
  std::vector<std::int32_t> region_of_row_;

  // Per frame.
  const Volume<std::uint8_t>* volume_ = nullptr;
  ProbePose pose_;
  std::vector<CrossingTet> crossing_;
  std::vector<std::int32_t> crossing_regions_;  // per crossing tet: first and last region, pairs
  std::vector<std::int32_t> region_start_;      // per region + 1: offset into region_tets_
  std::vector<std::int32_t> region_tets_;       // crossing indices, grouped by region
  std::vector<std::int32_t> region_fill_;       // scratch cursor per region while listing
};

}  // namespace ultrasim::imaging
