#pragma once

// The kiosk's colours, in one place so the screen stays consistent. Internal to render/.

#include <array>
#include <cstdint>

namespace ultrasim::render::detail {

struct Rgba8 {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  std::uint8_t a = 255;
};

inline constexpr Rgba8 with_alpha(Rgba8 c, std::uint8_t a) {
  return {c.r, c.g, c.b, a};
}
inline constexpr std::array<float, 4> to_float(Rgba8 c) {
  return {c.r / 255.0f, c.g / 255.0f, c.b / 255.0f, c.a / 255.0f};
}

namespace theme {
inline constexpr Rgba8 kBackground{16, 20, 24};  // #101418, the whole screen
inline constexpr Rgba8 kHeader{11, 14, 17};      // title bar
inline constexpr Rgba8 kPanel3d{22, 28, 34};     // behind the 3D view
inline constexpr Rgba8 kPanelBscan{0, 0, 0};     // behind the B-scan: black, as on a scanner
inline constexpr Rgba8 kPanelBorder{44, 53, 63};
inline constexpr Rgba8 kAccent{64, 186, 208};  // teal: title mark, image plane frame
inline constexpr Rgba8 kTextPrimary{218, 224, 230};
inline constexpr Rgba8 kTextSecondary{128, 140, 152};
inline constexpr Rgba8 kScale{170, 180, 190};  // depth ticks and labels
inline constexpr Rgba8 kWarning{232, 62, 52};  // no contact
inline constexpr Rgba8 kFrozen{240, 172, 40};  // frozen tag, collider ring
inline constexpr Rgba8 kBounds{62, 72, 84};    // scene bounding box
inline constexpr Rgba8 kProbeBody{196, 204, 212};
inline constexpr Rgba8 kProbeHead{120, 132, 146};
inline constexpr Rgba8 kProbeEdge{40, 46, 54};
inline constexpr Rgba8 kProbeMarker{64, 186, 208};  // orientation mark on the +x side
}  // namespace theme

}  // namespace ultrasim::render::detail
