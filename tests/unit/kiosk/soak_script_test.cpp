// The soak session's script: reproducible from its seed, as long as asked, every pose valid for
// the scripted probe, and the warm-up switching through every live method.

#include "ultrasim/kiosk/soak_script.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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

// A second case far from the first, pressed less deep.
config::CaseScan other_scan() {
  config::CaseScan s;
  s.start_mm = {100.0, 0.0, 0.0};
  s.end_mm = {120.0, 0.0, 0.0};
  s.press_depth_mm = 4.0;
  return s;
}

Script soak_script(const config::CaseScan& scan, double depth_mm, double duration_s,
                   std::uint64_t seed) {
  const SoakCase one[] = {{scan, depth_mm}};
  return kiosk::soak_script(one, duration_s, seed);
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

TEST(SoakScript, WithACaseListItWarmsUpOnEachAndPicksCasesAtRandomWithTheProbeLifted) {
  const SoakCase cases[] = {{scan(), 40.0}, {other_scan(), 30.0}};
  EXPECT_THROW(kiosk::soak_script(cases, 1.5 * kSoakWarmUpS, 1), std::invalid_argument);
  const Script s = kiosk::soak_script(cases, 600.0, 5);
  EXPECT_NO_THROW(drivers::sim_probe::ScriptedProbe probe(s.keyframes));
  const auto warm_up_us = static_cast<hal::TimestampUs>(soak_warm_up_s(2) * 1e6);
  int switches = 0, after_warm_up = 0, current = 0;
  std::set<sim::EngineKind> seen_on_second;
  for (const auto& c : s.controls) {
    if (current == 1 && c.method && c.time_us <= warm_up_us) seen_on_second.insert(*c.method);
    if (!c.case_index) continue;
    ++switches;
    after_warm_up += c.time_us > warm_up_us;
    EXPECT_NE(*c.case_index, current);
    current = *c.case_index;
    EXPECT_EQ(c.depth_mm, current == 0 ? 40.0 : 30.0);
    EXPECT_FALSE(c.frozen);
    // Lifted when the case changes: the keyframe before the switch is 5 mm above the skin.
    const auto before = std::find_if(s.keyframes.rbegin(), s.keyframes.rend(),
                                     [&](const auto& k) { return k.time_us <= c.time_us; });
    ASSERT_NE(before, s.keyframes.rend());
    EXPECT_LT(before->position_mm.z(), -4.9);
  }
  EXPECT_EQ(seen_on_second.size(), 5u);
  EXPECT_GE(switches, 2 + 5);  // to the second and back in the warm-up, then a few more
  EXPECT_GE(after_warm_up, 5);
  // Every pose on the case in use: the second case's presses stay within 1.5 × its 4 mm.
  for (const auto& k : s.keyframes) {
    if (k.position_mm.x() > 50.0) {
      EXPECT_LE(k.position_mm.z(), 6.0 + 1e-9);
    }
  }
}

}  // namespace
}  // namespace ultrasim::kiosk
