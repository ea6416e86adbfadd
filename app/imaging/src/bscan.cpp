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

std::optional<Eigen::Vector2d> BscanGrid::pixel_to_plane_mm(int col, int row) const {
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

std::uint8_t apply_gain(float echo, double gain_db) {
  const double v = std::round(echo * std::pow(10.0, gain_db / 20.0));
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
      pixel = echo < 0 ? background : apply_gain(echo, settings.gain_db);
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
      if (echo >= 0) pixel = apply_gain(echo, settings.gain_db);
    }
  }
}

}  // namespace ultrasim::imaging
