#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"

namespace ultrasim::drivers::sim_probe {

// A probe motion written as text, one keyframe per line (sweeps, tilts and presses are moves
// between keyframes; ScriptedProbe interpolates):
//
//   # time_s  x_mm  y_mm  z_mm  rx_deg  ry_deg  rz_deg  [marker]
//   0.0       -2   -12    -5    0       0       0
//   1.0       -2   -12    0.5   0       0       0       sweep-start
//   3.0       -2    12    0.5   15      0       0       tilted
//
// Position in patient space (+z into the tissue); orientation as a rotation vector (axis ×
// angle in degrees: rx = 15 tilts the probe 15° about patient x); an optional marker names the
// moment (a headless run takes its screenshots there). '#' starts a comment; blank lines are
// skipped. Times must increase.
//
// Throws std::invalid_argument naming source:line and the field that is wrong (not a number,
// missing, not finite, time not increasing), or that no keyframe was given. Allocates.
std::vector<Keyframe> parse_motion(std::string_view text, const std::string& source);

// parse_motion() of a file; the error names the path (also when it cannot be read).
std::vector<Keyframe> read_motion_file(const std::filesystem::path& path);

}  // namespace ultrasim::drivers::sim_probe
