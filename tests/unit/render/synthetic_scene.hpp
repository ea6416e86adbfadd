#pragma once

// A synthetic frame for render tests, the screenshot demo and the benchmark: a 10×5×8-node grid
// box of tissue with a dent under the probe, the probe pressing into it, a collider sphere and a
// speckle B-scan with a vessel and a fascia line. Deterministic (fixed seed). frame's spans point
// into the vectors beside it: move a SyntheticScene, never copy it.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "ultrasim/render/frame_input.hpp"

namespace ultrasim::render::testing {

struct SyntheticScene {
  std::vector<float> positions_mm;
  std::vector<float> displacement_mm;
  std::vector<std::uint32_t> lines;
  std::vector<std::uint8_t> bscan;
  FrameInput frame;
};

inline constexpr int kGridX = 10;
inline constexpr int kGridY = 5;
inline constexpr int kGridZ = 8;

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
      float echo = 0.55f;
      const float fascia = std::exp(-std::pow((z_mm - 8.0f - 0.04f * x_mm) / 0.6f, 2.0f));
      echo += 1.6f * fascia;
      const float r_mm = std::hypot(x_mm - 3.0f, z_mm - 20.0f);
      if (r_mm < 5.0f) echo = 0.04f;                                    // lumen
      echo += 1.2f * std::exp(-std::pow((r_mm - 5.3f) / 0.5f, 2.0f));   // wall
      echo += 0.8f * std::exp(-std::pow((z_mm - 33.0f) / 1.2f, 2.0f));  // deep layer
      echo *= std::exp(-0.012f * z_mm);                                 // net of TGC
      const float db = 20.0f * std::log10(std::max(echo * a, 1e-4f));
      const float grey = (db + 30.0f) / 40.0f * 255.0f;  // 40 dB dynamic range
      out[static_cast<std::size_t>(y) * width_px + x] =
          static_cast<std::uint8_t>(std::clamp(grey, 0.0f, 255.0f));
    }
  }
  return out;
}

inline SyntheticScene make_synthetic_scene(int bscan_width_px = 256, int bscan_height_px = 270) {
  SyntheticScene s;
  const float size_mm[3] = {90.0f, 40.0f, 56.0f};
  const float dent_mm = 5.0f;
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
        // The dent: a Gaussian push down (+z) under the probe, fading with depth.
        const float r2 =
            (x - cx) * (x - cx) / (2 * 16.0f * 16.0f) + (y - cy) * (y - cy) / (2 * 12.0f * 12.0f);
        const float uz = dent_mm * std::exp(-r2) * (1.0f - z / size_mm[2]);
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

}  // namespace ultrasim::render::testing
