#pragma once

#include <array>

namespace ultrasim::imaging {

enum class ProbeKind { kLinear, kConvex };

// Transducer geometry. Linear: a rectangle of width_mm × depth_mm below the face. Convex: an
// annular sector of fan_angle_deg, from the face arc of radius_mm down to depth_mm below it.
struct ProbeGeometry {
  ProbeKind kind = ProbeKind::kLinear;
  double width_mm = 38.0;       // linear: aperture width
  double depth_mm = 40.0;       // imaging depth below the face, both kinds
  double radius_mm = 50.0;      // convex: radius of curvature of the face
  double fan_angle_deg = 60.0;  // convex: total opening angle of the sector
};

// Grey levels in case volumes are log-compressed echo amplitudes spanning this many dB from
// 0 to 255, as a scanner's B-mode output does; display controls act on that dB scale.
inline constexpr double kRecordedDynamicRangeDb = 60.0;

// Time-gain compensation: sliders at equally spaced depths from the face (first) to the
// imaging depth (last), interpolated linearly between them, as on a scanner's panel.
inline constexpr int kTgcSliders = 8;

// How the B-scan is sampled from the deformed tissue; all three give the same image (±1 grey
// level, tested). Scan-line acquisition always uses the reference.
enum class SlicerMethod {
  kFast,       // cut the mesh with the image plane and scan-convert the cuts (multithreaded)
  kPublished,  // the dissertation's row subdivision over 32 regions (multithreaded)
  kReference,  // locate every pixel in the deformed mesh (single thread; the ground truth)
};

// The B-scan image grid and display mapping.
struct BscanSettings {
  SlicerMethod slicer = SlicerMethod::kFast;
  int width_px = 512;
  int height_px = 512;
  double gain_db = 0.0;                      // overall gain added to every echo level (dB)
  std::array<double, kTgcSliders> tgc_db{};  // depth-dependent gain (dB), face to imaging depth
  double dynamic_range_db = kRecordedDynamicRangeDb;  // echo range shown from black to white
  int background_grey = 0;  // grey level shown outside the volume or the mesh
  // Acquire along scan lines, as a scanner does, then scan-convert to the width_px × height_px
  // display: 0 slices the display grid directly. A convex probe's lateral detail then thins
  // with depth as its lines fan out.
  int scan_lines = 0;
  int samples_per_line = 512;
};

}  // namespace ultrasim::imaging
