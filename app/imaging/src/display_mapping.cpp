#include "ultrasim/imaging/display_mapping.hpp"

#include <algorithm>
#include <cmath>

namespace ultrasim::imaging {

namespace {

std::uint8_t map_grey(std::uint8_t grey, double gain_db, double dynamic_range_db) {
  // Grey 0 is no echo at all (below the recording's floor, or outside the tissue): no gain
  // brings it up, so lumens and the background stay black.
  if (grey == 0) return 0;
  const double level_db = grey * kRecordedDynamicRangeDb / 255.0;
  const double floor_db = kRecordedDynamicRangeDb - dynamic_range_db;
  const double v = 255.0 * (level_db + gain_db - floor_db) / dynamic_range_db;
  return static_cast<std::uint8_t>(std::clamp(std::round(v), 0.0, 255.0));
}

}  // namespace

double DisplayMapping::tgc_at(const std::array<double, kTgcSliders>& tgc_db, double depth_mm,
                              double imaging_depth_mm) {
  const double t = std::clamp(depth_mm / imaging_depth_mm, 0.0, 1.0) * (kTgcSliders - 1);
  const int i = std::min(static_cast<int>(t), kTgcSliders - 2);
  const double f = t - i;
  return tgc_db[i] * (1 - f) + tgc_db[i + 1] * f;
}

DisplayMapping::DisplayMapping(const BscanGrid& grid, const BscanSettings& settings)
    : width_px_(grid.width_px()),
      height_px_(grid.height_px()),
      imaging_depth_mm_(grid.imaging_depth_mm()),
      settings_(settings),
      pixel_bin_(static_cast<std::size_t>(width_px_) * height_px_, kOutside),
      lut_(kDepthBins - 1) {
  const int bins = kDepthBins - 1;
  for (int b = 0; b < bins; ++b) {
    const double depth = (b + 0.5) * imaging_depth_mm_ / bins;
    const double gain = settings.gain_db + tgc_at(settings.tgc_db, depth, imaging_depth_mm_);
    for (int g = 0; g < 256; ++g) {
      lut_[b][g] = map_grey(static_cast<std::uint8_t>(g), gain, settings.dynamic_range_db);
    }
  }
  for (int row = 0; row < height_px_; ++row) {
    for (int col = 0; col < width_px_; ++col) {
      const auto depth = grid.pixel_depth_mm(col, row);
      if (!depth) continue;
      const int b = std::clamp(static_cast<int>(*depth / imaging_depth_mm_ * bins), 0, bins - 1);
      pixel_bin_[static_cast<std::size_t>(row) * width_px_ + col] = static_cast<std::uint8_t>(b);
    }
  }
}

void DisplayMapping::apply_rows(std::span<std::uint8_t> image, int row_begin, int row_end) const {
  const std::size_t begin = static_cast<std::size_t>(row_begin) * width_px_;
  const std::size_t end = static_cast<std::size_t>(row_end) * width_px_;
  for (std::size_t i = begin; i < end; ++i) {
    const std::uint8_t b = pixel_bin_[i];
    if (b != kOutside) image[i] = lut_[b][image[i]];
  }
}

std::uint8_t DisplayMapping::map(std::uint8_t grey, double depth_mm) const {
  const double gain = settings_.gain_db + tgc_at(settings_.tgc_db, depth_mm, imaging_depth_mm_);
  return map_grey(grey, gain, settings_.dynamic_range_db);
}

}  // namespace ultrasim::imaging
