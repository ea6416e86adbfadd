#pragma once

#include <cstdint>
#include <span>

namespace ultrasim::tools {

// A family of square fiducial codes as AprilTag describes one: each code's bit (nbits − 1 − i)
// is the patch at (bit_x[i], bit_y[i]) on the tag's grid (coordinates read as signed 32-bit).
struct CodeFamily {
  std::span<const std::uint64_t> codes;
  std::span<const std::uint32_t> bit_x;
  std::span<const std::uint32_t> bit_y;
};

// The family's worst case: the fewest bits in which a code differs from another code in any of
// its four rotations, or from itself turned by 90°, 180° or 270° (a camera sees every rotation).
// Throws std::invalid_argument when a patch's rotation is not a patch of the layout.
int min_distance_under_rotation(const CodeFamily& family);

}  // namespace ultrasim::tools
