#pragma once

// The displacement colour ramp, blue (0) → cyan → green → yellow → red (full scale). The same
// table feeds the mesh shader (as a uniform array) and the on-screen colour bar, so the legend
// cannot drift from the picture. Internal to render/.

#include <algorithm>
#include <array>

namespace ultrasim::render::detail {

inline constexpr int kRampStops = 5;
inline constexpr std::array<std::array<float, 3>, kRampStops> kRamp = {{
    {0.22f, 0.42f, 0.96f},  // 0: blue
    {0.12f, 0.76f, 0.94f},  // cyan
    {0.32f, 0.86f, 0.36f},  // green
    {0.98f, 0.80f, 0.16f},  // yellow
    {0.96f, 0.22f, 0.16f},  // full scale: red
}};

// Colour at t in [0, 1] (clamped), linear between stops; matches the mesh shader.
inline std::array<float, 3> ramp_colour(float t) {
  const float x = std::clamp(t, 0.0f, 1.0f) * (kRampStops - 1);
  const int i = std::min(static_cast<int>(x), kRampStops - 2);
  const float f = x - static_cast<float>(i);
  std::array<float, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = kRamp[i][k] + (kRamp[i + 1][k] - kRamp[i][k]) * f;
  return c;
}

}  // namespace ultrasim::render::detail
