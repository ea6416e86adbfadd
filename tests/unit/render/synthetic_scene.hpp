#pragma once

// A synthetic frame for render tests, the screenshot demo and the benchmark: a 10×5×8-node grid
// box of tissue with a dent under the probe, the probe pressing into it, a collider sphere and a
// speckle B-scan with a vessel and a fascia line; add_synthetic_structures() adds a vein squashed
// under the probe, a round artery, a nerve and a bone. Deterministic (fixed seed). frame's spans
// point into the vectors beside it: move a SyntheticScene, never copy it.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "synthetic_surfaces.hpp"
#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::render::testing {

struct SyntheticScene {
  std::vector<float> positions_mm;
  std::vector<float> displacement_mm;
  std::vector<std::uint32_t> lines;
  std::vector<std::uint8_t> bscan;
  std::vector<SyntheticSurface> structures;
  std::vector<SurfaceView> surface_views;
  FrameInput frame;
};

inline constexpr int kGridX = 10;
inline constexpr int kGridY = 5;
inline constexpr int kGridZ = 8;
inline constexpr float kTissueSizeMm[3] = {90.0f, 40.0f, 56.0f};
inline constexpr float kDentMm = 5.0f;

// The dent under the probe: a Gaussian push down (+z), fading with depth, at a rest point.
inline float dent_displacement_mm(float x_mm, float y_mm, float z_mm) {
  const float cx = 0.5f * kTissueSizeMm[0];
  const float cy = 0.5f * kTissueSizeMm[1];
  const float r2 = (x_mm - cx) * (x_mm - cx) / (2 * 16.0f * 16.0f) +
                   (y_mm - cy) * (y_mm - cy) / (2 * 12.0f * 12.0f);
  return kDentMm * std::exp(-r2) * (1.0f - z_mm / kTissueSizeMm[2]);
}

// Speckle: the magnitude of a sum of random phasors (Rayleigh distributed), smoothed along the
// beam, log-compressed; a dark round vessel with a bright wall, a bright fascia, attenuation.
inline std::vector<std::uint8_t> make_speckle_bscan(int width_px, int height_px, float width_mm,
                                                    float depth_mm) {
  std::mt19937 rng(12345);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<float> amplitude(static_cast<std::size_t>(width_px) * height_px);
  for (float& a : amplitude) a = std::hypot(normal(rng), normal(rng));
  std::vector<std::uint8_t> out(amplitude.size());
  const float mm_per_px_x = width_mm / static_cast<float>(width_px);
  const float mm_per_px_z = depth_mm / static_cast<float>(height_px);
  for (int y = 0; y < height_px; ++y) {
    for (int x = 0; x < width_px; ++x) {
      // Axial smoothing: speckle is elongated laterally less than axially at this scale.
      float a = 0.0f;
      for (int k = -1; k <= 1; ++k) {
        const int yy = std::clamp(y + k, 0, height_px - 1);
        a += amplitude[static_cast<std::size_t>(yy) * width_px + x];
      }
      a /= 3.0f;
      const float x_mm = (static_cast<float>(x) + 0.5f) * mm_per_px_x - 0.5f * width_mm;
      const float z_mm = (static_cast<float>(y) + 0.5f) * mm_per_px_z;
      float echo = 0.30f;
      const float fascia = std::exp(-std::pow((z_mm - 8.0f - 0.04f * x_mm) / 0.6f, 2.0f));
      echo += 1.6f * fascia;
      const float r_mm = std::hypot(x_mm - 3.0f, z_mm - 20.0f);
      if (r_mm < 5.0f) echo = 0.04f;                                    // lumen
      echo += 1.2f * std::exp(-std::pow((r_mm - 5.3f) / 0.5f, 2.0f));   // wall
      echo += 0.8f * std::exp(-std::pow((z_mm - 33.0f) / 1.2f, 2.0f));  // deep layer
      echo *= std::exp(-0.012f * z_mm);                                 // net of TGC
      const float db = 20.0f * std::log10(std::max(echo * a, 1e-4f));
      const float grey = (db + 26.0f) / 44.0f * 255.0f;  // 44 dB dynamic range
      out[static_cast<std::size_t>(y) * width_px + x] =
          static_cast<std::uint8_t>(std::clamp(grey, 0.0f, 255.0f));
    }
  }
  return out;
}

inline SyntheticScene make_synthetic_scene(int bscan_width_px = 256, int bscan_height_px = 270) {
  SyntheticScene s;
  const float* size_mm = kTissueSizeMm;
  const float dent_mm = kDentMm;
  const float cx = 0.5f * size_mm[0];
  const float cy = 0.5f * size_mm[1];
  const auto node = [](int i, int j, int k) {
    return static_cast<std::uint32_t>((k * kGridY + j) * kGridX + i);
  };
  for (int k = 0; k < kGridZ; ++k) {
    for (int j = 0; j < kGridY; ++j) {
      for (int i = 0; i < kGridX; ++i) {
        const float x = size_mm[0] * static_cast<float>(i) / (kGridX - 1);
        const float y = size_mm[1] * static_cast<float>(j) / (kGridY - 1);
        const float z = size_mm[2] * static_cast<float>(k) / (kGridZ - 1);
        const float uz = dent_displacement_mm(x, y, z);
        s.positions_mm.insert(s.positions_mm.end(), {x, y, z + uz});
        s.displacement_mm.push_back(uz);
      }
    }
  }
  for (int k = 0; k < kGridZ; ++k) {
    for (int j = 0; j < kGridY; ++j) {
      for (int i = 0; i < kGridX; ++i) {
        if (i + 1 < kGridX) s.lines.insert(s.lines.end(), {node(i, j, k), node(i + 1, j, k)});
        if (j + 1 < kGridY) s.lines.insert(s.lines.end(), {node(i, j, k), node(i, j + 1, k)});
        if (k + 1 < kGridZ) s.lines.insert(s.lines.end(), {node(i, j, k), node(i, j, k + 1)});
      }
    }
  }
  const float width_mm = 38.0f;
  const float depth_mm = 40.0f;
  s.bscan = make_speckle_bscan(bscan_width_px, bscan_height_px, width_mm, depth_mm);

  FrameInput& f = s.frame;
  f.mesh.node_positions_mm = s.positions_mm;
  f.mesh.line_indices = s.lines;
  f.mesh.node_displacement_mm = s.displacement_mm;
  f.bscan = {s.bscan, bscan_width_px, bscan_height_px, width_mm, depth_mm, true, false};
  // Probe face at the bottom of the dent, tilted 10° about the beam-normal (y) axis.
  const float tilt = 10.0f * 3.14159265f / 180.0f;
  const float c = std::cos(tilt);
  const float sn = std::sin(tilt);
  f.probe.probe_to_patient = {c, 0, -sn, 0, 0, 1, 0, 0, sn, 0, c, 0, cx, cy, dent_mm, 1};
  f.probe.face_width_mm = width_mm;
  f.probe.image_depth_mm = depth_mm;
  f.probe.collider_center_mm = {cx, cy, dent_mm - 9.0f};
  f.probe.collider_radius_mm = 9.0f;
  f.scene_min_mm = {0.0f, 0.0f, 0.0f};
  f.scene_max_mm = {size_mm[0], size_mm[1], size_mm[2]};
  f.frame_index = 1234;
  return s;
}

// Four closed tubes along the limb (+y) through the tissue, in the kiosk's colours, moved by the
// dent like the mesh: a vein beside the probe, squashed flat under it (veins collapse); an
// artery under the probe where the B-scan shows its vessel, pushed down but round (arteries do
// not); a thin nerve; a deep bone. About total_triangles triangles in all (0: none).
inline void add_synthetic_structures(SyntheticScene& s, int total_triangles = 15000) {
  s.structures.clear();
  s.surface_views.clear();
  s.frame.surfaces = {};
  if (total_triangles <= 0) return;
  const auto [around, along] = tube_resolution(total_triangles / 4);
  const float cy = 0.5f * kTissueSizeMm[1];
  const float y0 = 1.0f;
  const float y1 = kTissueSizeMm[1] - 1.0f;
  // Closeness to the probe along the tube: 1 under it, fading over about 12 mm.
  const auto under_probe = [cy](float x_mm, float y_mm) {
    const float cx = 0.5f * kTissueSizeMm[0];
    return std::exp(-(x_mm - cx) * (x_mm - cx) / (2 * 16.0f * 16.0f) -
                    (y_mm - cy) * (y_mm - cy) / (2 * 12.0f * 12.0f));
  };
  const auto round_tube = [&](float x_mm, float z_mm, float radius_mm) {
    TubeShape t;
    t.y0_mm = y0;
    t.y1_mm = y1;
    t.centre_x_mm = [x_mm](float) { return x_mm; };
    t.centre_z_mm = [x_mm, z_mm](float y) { return z_mm + dent_displacement_mm(x_mm, y, z_mm); };
    t.half_x_mm = [radius_mm](float) { return radius_mm; };
    t.half_z_mm = [radius_mm](float) { return radius_mm; };
    return t;
  };

  const float vein_x = 36.0f;
  const float vein_z = 17.0f;
  const float vein_r = 5.5f;
  TubeShape vein = round_tube(vein_x, vein_z, vein_r);
  // Squashed to a third of its height and widened (the wall keeps its length) under the probe.
  vein.half_z_mm = [=](float y) { return vein_r * (1.0f - 0.68f * under_probe(vein_x, y)); };
  vein.half_x_mm = [=](float y) { return vein_r * (1.0f + 0.35f * under_probe(vein_x, y)); };
  vein.centre_z_mm = [=](float y) {
    return vein_z + dent_displacement_mm(vein_x, y, vein_z) + 2.5f * under_probe(vein_x, y);
  };
  // The artery sits where the B-scan draws its vessel: 3 mm lateral, 20 mm deep in the probe
  // frame, tilted 10° (see make_synthetic_scene).
  s.structures.push_back(make_tube(vein, around, along));
  s.structures.push_back(make_tube(round_tube(51.4f, 21.0f, 4.5f), around, along));
  s.structures.push_back(make_tube(round_tube(61.0f, 15.0f, 2.2f), around, along));
  s.structures.push_back(make_tube(round_tube(44.0f, 44.0f, 7.0f), around, along));
  const std::array<std::array<float, 4>, 4> colours = {kVeinRgba, kArteryRgba, kNerveRgba,
                                                       kBoneRgba};
  for (std::size_t i = 0; i < s.structures.size(); ++i) {
    s.surface_views.push_back(s.structures[i].view(colours[i]));
  }
  s.frame.surfaces = s.surface_views;
}

}  // namespace ultrasim::render::testing
