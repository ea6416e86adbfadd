// The soak session's script: reproducible from its seed, as long as asked, every pose valid for
// the scripted probe, and the warm-up switching through every live method.

#include "ultrasim/kiosk/soak_script.hpp"

#include <gtest/gtest.h>

#include <set>
#include <stdexcept>

#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"

namespace ultrasim::kiosk {
namespace {

config::CaseScan scan() {
  config::CaseScan s;
  s.start_mm = {-2.0, -12.0, 0.0};
  s.end_mm = {-2.0, 12.0, 0.0};
  s.press_depth_mm = 8.0;
  return s;
}

TEST(SoakScript, TheSameSeedGivesTheSameSessionAndAnotherSeedAnother) {
  const Script a = soak_script(scan(), 40.0, 60.0, 7), b = soak_script(scan(), 40.0, 60.0, 7),
               c = soak_script(scan(), 40.0, 60.0, 8);
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  for (std::size_t i = 0; i < a.keyframes.size(); ++i) {
    EXPECT_EQ(a.keyframes[i].time_us, b.keyframes[i].time_us);
    EXPECT_EQ(a.keyframes[i].position_mm, b.keyframes[i].position_mm);
  }
  EXPECT_EQ(a.controls.size(), b.controls.size());
  EXPECT_FALSE(a.keyframes.size() == c.keyframes.size() &&
               a.keyframes.back().position_mm == c.keyframes.back().position_mm);
}

TEST(SoakScript, LastsAsLongAsAskedWithValidPosesAndPressesInRange) {
  const Script s = soak_script(scan(), 40.0, 120.0, 3);
  EXPECT_GE(s.keyframes.back().time_us, 120'000'000);
  EXPECT_LT(s.keyframes.back().time_us, 123'000'000);
  for (const auto& k : s.keyframes) {
    EXPECT_GE(k.position_mm.z(), -5.0 - 1e-9);  // at most 5 mm above the skin
    EXPECT_LE(k.position_mm.z(), 12.0 + 1e-9);  // at most 1.5 × the press depth
  }
  // The scripted probe accepts it: increasing times, finite values, unit quaternions.
  EXPECT_NO_THROW(drivers::sim_probe::ScriptedProbe probe(s.keyframes));
}

TEST(SoakScript, TheWarmUpVisitsEveryLiveMethodAndEndsOnTheDefault) {
  const Script s = soak_script(scan(), 40.0, 30.0, 1);
  std::set<sim::EngineKind> seen;
  sim::EngineKind last = sim::EngineKind::kHyperelasticFem;
  for (const auto& c : s.controls) {
    if (c.time_us > static_cast<hal::TimestampUs>(kSoakWarmUpS * 1e6)) break;
    if (c.method) {
      seen.insert(*c.method);
      last = *c.method;
    }
  }
  EXPECT_EQ(seen.size(), 5u);
  EXPECT_FALSE(seen.contains(sim::EngineKind::kHyperelasticFem));
  EXPECT_EQ(last, sim::EngineKind::kExactFem);
  EXPECT_THROW(soak_script(scan(), 40.0, 5.0, 1), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::kiosk
