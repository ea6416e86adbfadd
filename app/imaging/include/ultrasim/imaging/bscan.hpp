#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/settings.hpp"
#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging {

// Where the probe is: the centre of its face and its axes (columns: lateral +x along the array,
// elevational +y, axial +z along the beam), all in patient space, mm.
struct ProbePose {
  Eigen::Vector3d face_center_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();

  Eigen::Vector3d to_patient(const Eigen::Vector2d& in_plane_mm) const {
    return face_center_mm + axes.col(0) * in_plane_mm.x() + axes.col(2) * in_plane_mm.y();
  }
};

// The image rectangle in the probe's plane, in the probe frame (lateral x, axial z), mm.
// Linear: [-width/2, width/2] × [0, depth]. Convex: the bounding box of the sector, whose arc
// apex is the face centre and whose centre of curvature lies radius_mm behind it.
struct ImageExtent {
  double x_min_mm, x_max_mm, z_min_mm, z_max_mm;
  double width_mm() const { return x_max_mm - x_min_mm; }
  double depth_mm() const { return z_max_mm - z_min_mm; }
};
ImageExtent image_extent(const ProbeGeometry& probe);

// Maps image pixels to points in the probe plane. Two layouts:
// - raster (the display): pixel (col, row) samples its centre in the image extent; row 0 is
//   nearest the face; for a convex probe, pixels outside the sector map to nothing.
// - scan lines (acquisition, as a scanner forms its image): col is the scan line, row the sample
//   along it; a linear probe's lines are parallel and evenly spaced across the aperture, a convex
//   probe's fan out at even angles from the centre of curvature. scan_convert() turns such an
//   image into a raster one.
class BscanGrid {
 public:
  enum class Layout { kRaster, kScanLines };

  BscanGrid(const ProbeGeometry& probe, int width_px, int height_px);
  static BscanGrid scan_lines(const ProbeGeometry& probe, int lines, int samples_per_line);

  std::optional<Eigen::Vector2d> pixel_to_plane_mm(int col, int row) const;
  // Depth of a pixel below the transducer face along its beam (z for a linear probe, distance
  // from the face arc for a convex one), or nothing outside a convex sector.
  std::optional<double> pixel_depth_mm(int col, int row) const;
  double imaging_depth_mm() const { return probe_.depth_mm; }
  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  const ImageExtent& extent() const { return extent_; }
  Layout layout() const { return layout_; }
  const ProbeGeometry& probe() const { return probe_; }

 private:
  ProbeGeometry probe_;
  ImageExtent extent_;
  int width_px_, height_px_;
  Layout layout_ = Layout::kRaster;
};

// Resamples a scan-line image onto a raster display grid of the same probe, interpolating
// bilinearly between neighbouring lines and samples (in angle and radius for a convex probe).
// Display pixels outside the sector or beyond the outermost line/sample centres by more than
// half a spacing get `background`. The per-pixel source positions are tabulated once; apply
// does not allocate and may run on disjoint row ranges from several threads.
class ScanConverter {
 public:
  ScanConverter(const BscanGrid& scan_lines, const BscanGrid& display, std::uint8_t background);
  void apply_rows(std::span<const std::uint8_t> lines_image, std::span<std::uint8_t> out,
                  int row_begin, int row_end) const;
  void apply(std::span<const std::uint8_t> lines_image, std::span<std::uint8_t> out) const {
    apply_rows(lines_image, out, 0, display_height_px_);
  }

 private:
  struct Tap {
    std::int32_t index = -1;  // top-left source sample (line-major rows), -1: background
    std::uint16_t line_weight = 0, sample_weight = 0;  // of the next line / sample, /65535
  };
  int lines_, samples_, display_width_px_, display_height_px_;
  std::uint8_t background_;
  std::vector<Tap> taps_;
};

// A sampled echo level as a grey level: rounded, clamped to [0, 255]. Slicers output the echo as
// recorded; the display controls (gain, TGC, dynamic range) are DisplayMapping's, applied after.
std::uint8_t echo_to_grey(float echo);

// B-scan of the undeformed volume: trilinear samples on the probe plane. `out` holds
// width_px × height_px bytes, row-major. Does not allocate.
void slice_undeformed(const Volume<std::uint8_t>& volume, const ProbePose& pose,
                      const BscanGrid& grid, const BscanSettings& settings,
                      std::span<std::uint8_t> out);

// B-scan of the deformed tissue, per pixel (the reference every fast slicer must match): locate
// the pixel in the deformed mesh, map it with the tet's barycentric coordinates back to the rest
// mesh, and sample the volume there. Pixels outside the deformed mesh or the volume show the
// background grey. `locator` must have been rebuilt on the deformed positions; `mesh` gives the
// rest positions. Does not allocate; read-only on its inputs.
void slice_deformed_reference(const Volume<std::uint8_t>& volume, const geometry::TetMesh& mesh,
                              const geometry::TetLocator& locator, const ProbePose& pose,
                              const BscanGrid& grid, const BscanSettings& settings,
                              std::span<std::uint8_t> out);

}  // namespace ultrasim::imaging
