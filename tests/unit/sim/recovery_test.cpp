// Recovery's names in reports and its order of gravity (one stitched frame reports the worst of
// its sub-volumes'; the stability map the worst of a run's frames).

#include <gtest/gtest.h>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {
namespace {

TEST(Recovery, KeysAreTheReportsNames) {
  EXPECT_EQ(recovery_key(Recovery::kNone), "none");
  EXPECT_EQ(recovery_key(Recovery::kSubstepped), "substepped");
  EXPECT_EQ(recovery_key(Recovery::kReset), "reset");
  EXPECT_EQ(recovery_key(Recovery::kKeptLastGood), "kept-last-good");
}

TEST(Recovery, CausesHaveTheReportsNames) {
  EXPECT_EQ(cause_key(DivergenceCause::kNone), "none");
  EXPECT_EQ(cause_key(DivergenceCause::kNonFinite), "non-finite");
  EXPECT_EQ(cause_key(DivergenceCause::kEnergy), "energy");
  EXPECT_EQ(cause_key(DivergenceCause::kRunaway), "runaway");
  EXPECT_EQ(cause_key(DivergenceCause::kInverted), "inverted");
  EXPECT_EQ(cause_key(DivergenceCause::kSeamTorn), "seam-torn");
  EXPECT_EQ(static_cast<int>(DivergenceCause::kSeamTorn) + 1, kDivergenceCauseCount);
}

TEST(Recovery, WorseOrdersNoneSubsteppedKeptLastGoodReset) {
  const Recovery order[] = {Recovery::kNone, Recovery::kSubstepped, Recovery::kKeptLastGood,
                            Recovery::kReset};
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      EXPECT_EQ(worse_recovery(order[a], order[b]), order[std::max(a, b)]) << a << ", " << b;
    }
  }
}

}  // namespace
}  // namespace ultrasim::sim
