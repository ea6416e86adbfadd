#include "ultrasim/drivers/sim_probe/motion_file.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace ultrasim::drivers::sim_probe {
namespace {

// A sweep, a tilt and a press, as a user writes them.
TEST(MotionFile, ReadsSweepsTiltsAndPresses) {
  const auto keys = parse_motion(R"(# time_s x y z rx ry rz [marker]
0.0   -2 -12 -5    0 0 0
1.0   -2 -12  0.5  0 0 0   sweep-start

3.0   -2  12  0.5  15 0 0  tilted   # a 15° tilt about x on the way
4.5   -2  12  8    15 0 0  pressed
)",
                                 "demo.motion");
  ASSERT_EQ(keys.size(), 4u);
  EXPECT_EQ(keys[1].time_us, 1'000'000);
  EXPECT_EQ(keys[1].marker, "sweep-start");
  EXPECT_EQ(keys[0].marker, "");
  EXPECT_EQ(keys[3].position_mm, Eigen::Vector3d(-2, 12, 8));
  EXPECT_NEAR(keys[2].orientation.angularDistance(Eigen::Quaterniond::Identity()), M_PI / 12,
              1e-12);
  const Eigen::Vector3d beam = keys[2].orientation * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(beam.x(), 0.0, 1e-12);  // about x: the beam tilts in the y–z plane
  // Plays through the scripted probe: halfway between the tilt and the press.
  ScriptedProbe probe(keys);
  EXPECT_NEAR(probe.latest(3'750'000)->position_mm.z(), 4.25, 1e-9);
}

void expect_error(std::string_view text, const std::string& needle) {
  try {
    parse_motion(text, "m.motion");
    FAIL() << "expected an error mentioning " << needle;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(MotionFile, ErrorsNameTheLineAndTheField) {
  expect_error("0 0 0 0 0 0 0\n1 0 0 zero 0 0 0\n", "m.motion:2: z_mm: not a number: 'zero'");
  expect_error("0 0 0 0 0\n", "m.motion:1: ry_deg: missing");
  expect_error("0 0 0 0 0 0 0\n0 0 0 0 0 0 0\n", "m.motion:2: time_s: must be >= 0 and increase");
  expect_error("0 0 0 0 0 0 0 a b\n", "m.motion:1: marker: one word");
  expect_error("0 0 0 nan 0 0 0\n", "m.motion:1: z_mm: not finite");
  expect_error("# only a comment\n", "m.motion: no keyframe");
  EXPECT_THROW(read_motion_file("/nonexistent/probe.motion"), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::drivers::sim_probe
