#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/imaging/bscan.hpp"
#include "ultrasim/imaging/settings.hpp"

namespace ultrasim::imaging {

// The scanner's display controls applied to sliced echo grey levels: overall gain, time-gain
// compensation over depth, and dynamic range. Grey levels are log-compressed (0–255 spans
// kRecordedDynamicRangeDb), so gains add in dB and the dynamic range rescales about the top:
//   grey_out = 255 · (level_db + gain_db + tgc_db(depth) − (R0 − DR)) / DR,  level_db = grey·R0/255
// With no gain, no TGC and DR = R0 the mapping is the identity. Grey 0 (no echo) stays 0.
class DisplayMapping {
 public:
  // Tabulates the mapping for every pixel of `grid` (its depth below the face: z for linear
  // probes, distance from the face arc for convex ones). Allocates; call when a control changes,
  // not every frame.
  DisplayMapping(const BscanGrid& grid, const BscanSettings& settings);

  // Maps `image` (grid-sized, row-major) in place; pixels outside a convex sector are left as
  // they are. Does not allocate. Rows [row_begin, row_end) only, so threads can share the work.
  void apply_rows(std::span<std::uint8_t> image, int row_begin, int row_end) const;
  void apply(std::span<std::uint8_t> image) const { apply_rows(image, 0, height_px_); }

  // One grey level at one depth, for tests and the UI's TGC curve.
  std::uint8_t map(std::uint8_t grey, double depth_mm) const;

  // TGC gain (dB) at a depth below the face, interpolated between the sliders.
  static double tgc_at(const std::array<double, kTgcSliders>& tgc_db, double depth_mm,
                       double imaging_depth_mm);

 private:
  static constexpr int kDepthBins = 256;
  int width_px_, height_px_;
  double imaging_depth_mm_;
  BscanSettings settings_;
  std::vector<std::uint8_t> pixel_bin_;             // per pixel: depth bin, or kOutside
  std::vector<std::array<std::uint8_t, 256>> lut_;  // per depth bin: grey in → grey out
  static constexpr std::uint8_t kOutside = 255;     // bins run 0..kDepthBins-2
};

}  // namespace ultrasim::imaging
