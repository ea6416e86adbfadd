#include "ultrasim/imaging/bscan.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace ultrasim::imaging {

namespace {
constexpr double kDegToRad = std::numbers::pi / 180.0;
}

ImageExtent image_extent(const ProbeGeometry& probe) {
  if (probe.kind == ProbeKind::kLinear) {
    return {-probe.width_mm / 2, probe.width_mm / 2, 0.0, probe.depth_mm};
  }
  const double half = probe.fan_angle_deg * kDegToRad / 2;
  const double outer = probe.radius_mm + probe.depth_mm;
  const double half_width = outer * std::sin(std::min(half, std::numbers::pi / 2));
  return {-half_width, half_width, -probe.radius_mm * (1 - std::cos(half)), probe.depth_mm};
}

BscanGrid::BscanGrid(const ProbeGeometry& probe, int width_px, int height_px)
    : probe_(probe), extent_(image_extent(probe)), width_px_(width_px), height_px_(height_px) {
  if (width_px < 1 || height_px < 1) throw std::invalid_argument("B-scan size must be >= 1 px");
}

BscanGrid BscanGrid::scan_lines(const ProbeGeometry& probe, int lines, int samples_per_line) {
  BscanGrid grid(probe, lines, samples_per_line);
  grid.layout_ = Layout::kScanLines;
  return grid;
}

std::optional<Eigen::Vector2d> BscanGrid::pixel_to_plane_mm(int col, int row) const {
  if (layout_ == Layout::kScanLines) {
    const double along = (row + 0.5) / height_px_ * probe_.depth_mm;
    const double across = (col + 0.5) / width_px_ - 0.5;  // -0.5 .. 0.5 over the lines
    if (probe_.kind == ProbeKind::kLinear) return Eigen::Vector2d(across * probe_.width_mm, along);
    const double angle = across * probe_.fan_angle_deg * kDegToRad;
    const double r = probe_.radius_mm + along;
    return Eigen::Vector2d(r * std::sin(angle), r * std::cos(angle) - probe_.radius_mm);
  }
  const double x = extent_.x_min_mm + (col + 0.5) * extent_.width_mm() / width_px_;
  const double z = extent_.z_min_mm + (row + 0.5) * extent_.depth_mm() / height_px_;
  if (probe_.kind == ProbeKind::kConvex) {
    // Polar coordinates about the centre of curvature, radius_mm behind the face centre.
    const double r = std::hypot(x, z + probe_.radius_mm);
    const double angle = std::atan2(x, z + probe_.radius_mm);
    if (r < probe_.radius_mm || r > probe_.radius_mm + probe_.depth_mm ||
        std::abs(angle) > probe_.fan_angle_deg * kDegToRad / 2) {
      return std::nullopt;
    }
  }
  return Eigen::Vector2d(x, z);
}

std::optional<double> BscanGrid::pixel_depth_mm(int col, int row) const {
  const auto plane = pixel_to_plane_mm(col, row);
  if (!plane) return std::nullopt;
  if (probe_.kind == ProbeKind::kLinear) return std::max(plane->y(), 0.0);
  return std::hypot(plane->x(), plane->y() + probe_.radius_mm) - probe_.radius_mm;
}

ScanConverter::ScanConverter(const BscanGrid& scan_lines, const BscanGrid& display,
                             std::uint8_t background)
    : lines_(scan_lines.width_px()),
      samples_(scan_lines.height_px()),
      display_width_px_(display.width_px()),
      display_height_px_(display.height_px()),
      background_(background),
      taps_(static_cast<std::size_t>(display.width_px()) * display.height_px()) {
  if (scan_lines.layout() != BscanGrid::Layout::kScanLines ||
      display.layout() != BscanGrid::Layout::kRaster) {
    throw std::invalid_argument("ScanConverter: needs a scan-line grid and a raster grid");
  }
  const ProbeGeometry& p = scan_lines.probe();
  for (int row = 0; row < display_height_px_; ++row) {
    for (int col = 0; col < display_width_px_; ++col) {
      const auto plane = display.pixel_to_plane_mm(col, row);
      if (!plane) continue;
      // Fractional line and sample coordinates of this display pixel (centres at i + 0.5).
      double line, sample;
      if (p.kind == ProbeKind::kLinear) {
        line = (plane->x() / p.width_mm + 0.5) * lines_;
        sample = plane->y() / p.depth_mm * samples_;
      } else {
        const double angle = std::atan2(plane->x(), plane->y() + p.radius_mm);
        const double r = std::hypot(plane->x(), plane->y() + p.radius_mm);
        line = (angle / (p.fan_angle_deg * kDegToRad) + 0.5) * lines_;
        sample = (r - p.radius_mm) / p.depth_mm * samples_;
      }
      line -= 0.5;
      sample -= 0.5;
      if (line < -0.5 || sample < -0.5 || line > lines_ - 0.5 || sample > samples_ - 0.5) continue;
      const int l0 = std::clamp(static_cast<int>(std::floor(line)), 0, std::max(lines_ - 2, 0));
      const int s0 = std::clamp(static_cast<int>(std::floor(sample)), 0, std::max(samples_ - 2, 0));
      const double fl = lines_ > 1 ? std::clamp(line - l0, 0.0, 1.0) : 0.0;
      const double fs = samples_ > 1 ? std::clamp(sample - s0, 0.0, 1.0) : 0.0;
      Tap& tap = taps_[static_cast<std::size_t>(row) * display_width_px_ + col];
      tap.index = s0 * lines_ + l0;
      tap.line_weight = static_cast<std::uint16_t>(std::lround(fl * 65535));
      tap.sample_weight = static_cast<std::uint16_t>(std::lround(fs * 65535));
    }
  }
}

void ScanConverter::apply_rows(std::span<const std::uint8_t> lines_image,
                               std::span<std::uint8_t> out, int row_begin, int row_end) const {
  const int dl = lines_ > 1 ? 1 : 0;
  const int ds = samples_ > 1 ? lines_ : 0;
  for (int row = row_begin; row < row_end; ++row) {
    for (int col = 0; col < display_width_px_; ++col) {
      const std::size_t i = static_cast<std::size_t>(row) * display_width_px_ + col;
      const Tap& tap = taps_[i];
      if (tap.index < 0) {
        out[i] = background_;
        continue;
      }
      const double fl = tap.line_weight / 65535.0, fs = tap.sample_weight / 65535.0;
      const auto v = [&](int offset) {
        return static_cast<double>(lines_image[tap.index + offset]);
      };
      const double top = v(0) * (1 - fl) + v(dl) * fl;
      const double bottom = v(ds) * (1 - fl) + v(ds + dl) * fl;
      out[i] = static_cast<std::uint8_t>(std::lround(top * (1 - fs) + bottom * fs));
    }
  }
}

std::uint8_t echo_to_grey(float echo) {
  const double v = std::round(echo);
  return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
}

void slice_undeformed(const Volume<std::uint8_t>& volume, const ProbePose& pose,
                      const BscanGrid& grid, const BscanSettings& settings,
                      std::span<std::uint8_t> out) {
  const auto background = static_cast<std::uint8_t>(settings.background_grey);
  for (int row = 0; row < grid.height_px(); ++row) {
    for (int col = 0; col < grid.width_px(); ++col) {
      std::uint8_t& pixel = out[static_cast<std::size_t>(row) * grid.width_px() + col];
      const auto plane = grid.pixel_to_plane_mm(col, row);
      const float echo = plane ? volume.sample_trilinear(pose.to_patient(*plane), -1.0f) : -1.0f;
      pixel = echo < 0 ? background : echo_to_grey(echo);
    }
  }
}

void slice_deformed_reference(const Volume<std::uint8_t>& volume, const geometry::TetMesh& mesh,
                              const geometry::TetLocator& locator, const ProbePose& pose,
                              const BscanGrid& grid, const BscanSettings& settings,
                              std::span<std::uint8_t> out) {
  const auto background = static_cast<std::uint8_t>(settings.background_grey);
  const auto& rest = mesh.rest_positions_mm;
  for (int row = 0; row < grid.height_px(); ++row) {
    for (int col = 0; col < grid.width_px(); ++col) {
      std::uint8_t& pixel = out[static_cast<std::size_t>(row) * grid.width_px() + col];
      pixel = background;
      const auto plane = grid.pixel_to_plane_mm(col, row);
      if (!plane) continue;
      const auto location = locator.locate(pose.to_patient(*plane));
      if (!location) continue;
      const auto& tet = mesh.tets[location->tet];
      Eigen::Vector3d undeformed = Eigen::Vector3d::Zero();
      for (int c = 0; c < 4; ++c) undeformed += location->barycentric[c] * rest[tet[c]];
      const float echo = volume.sample_trilinear(undeformed, -1.0f);
      if (echo >= 0) pixel = echo_to_grey(echo);
    }
  }
}

}  // namespace ultrasim::imaging
