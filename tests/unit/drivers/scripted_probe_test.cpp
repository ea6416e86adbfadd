#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"

#include <gtest/gtest.h>

namespace ultrasim::drivers::sim_probe {
namespace {

TEST(ScriptedProbe, InterpolatesBetweenKeyframesAndHoldsOutside) {
  const Eigen::Quaterniond turned(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  ScriptedProbe probe(
      {{0, {0, 0, 0}, Eigen::Quaterniond::Identity(), ""}, {1'000'000, {10, 0, 4}, turned, "end"}});
  auto mid = probe.latest(500'000);
  ASSERT_TRUE(mid.has_value());
  EXPECT_TRUE(mid->position_mm.isApprox(Eigen::Vector3d(5, 0, 2)));
  EXPECT_NEAR(mid->orientation.angularDistance(Eigen::Quaterniond::Identity()), M_PI / 4, 1e-12);
  EXPECT_TRUE(hal::is_valid(*mid));
  EXPECT_EQ(mid->timestamp_us, 500'000);
  EXPECT_TRUE(probe.latest(-5)->position_mm.isZero());
  EXPECT_TRUE(probe.latest(9'000'000)->position_mm.isApprox(Eigen::Vector3d(10, 0, 4)));
}

TEST(ScriptedProbe, SequenceNumbersIncrease) {
  ScriptedProbe probe({{0, {0, 0, 0}, Eigen::Quaterniond::Identity(), ""}});
  const auto first = probe.latest(0)->sequence;
  const auto second = probe.latest(1)->sequence;
  EXPECT_EQ(first + 1, second);
}

TEST(ScriptedProbe, RejectsBadScripts) {
  EXPECT_THROW(ScriptedProbe({}), std::invalid_argument);
  EXPECT_THROW(ScriptedProbe({{0, {0, 0, 0}, Eigen::Quaterniond::Identity(), ""},
                              {0, {1, 0, 0}, Eigen::Quaterniond::Identity(), ""}}),
               std::invalid_argument);
  EXPECT_THROW(ScriptedProbe({{0, {std::nan(""), 0, 0}, Eigen::Quaterniond::Identity(), ""}}),
               std::invalid_argument);
}

TEST(SweepPressScript, HoversSweepsPressesAndReleases) {
  const auto keys = sweep_press_script({-2, -12, 0}, {-2, 12, 0}, 8.0);
  ScriptedProbe probe(keys);
  const auto find = [&](const std::string& marker) {
    for (const auto& k : keys)
      if (k.marker == marker) return k;
    ADD_FAILURE() << "no marker " << marker;
    return keys.front();
  };
  EXPECT_LT(find("lifted").position_mm.z(), 0.0);  // above the skin
  EXPECT_NEAR(find("sweep-start").position_mm.y(), -12, 1e-12);
  EXPECT_NEAR(find("sweep-end").position_mm.y(), 12, 1e-12);
  EXPECT_NEAR(find("pressed").position_mm.z(), 8.0, 1e-12);
  EXPECT_NEAR(find("rest").position_mm.z(), 0.5, 1e-12);
  EXPECT_GT(find("released").time_us, find("pressed").time_us);
  EXPECT_EQ(probe.duration_us(), keys.back().time_us);
}

}  // namespace
}  // namespace ultrasim::drivers::sim_probe
