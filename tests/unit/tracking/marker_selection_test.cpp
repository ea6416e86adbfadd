// The published marker selection (dissertation, appendix D): 120 unique 3×3 patterns, 60
// positives and their negatives, and the exhaustive search over C(60, 6) whose best set differs
// in at least 2 patches everywhere with a similarity sum of 568.

#include "ultrasim/tracking/marker_selection.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <set>

namespace ultrasim::tracking {
namespace {

TEST(MarkerSelection, RotationTurnsTheGridClockwise) {
  // 1 0 0      0 0 1
  // 0 0 0  ->  0 0 0   (the top-left patch goes to the top right)
  // 0 0 0      0 0 0
  EXPECT_EQ(rotate_90(0b000'000'001), 0b000'000'100);
  EXPECT_EQ(rotate_90(0b000'000'100), 0b100'000'000);
  Pattern p = 0b011'010'110;
  for (int i = 0; i < 4; ++i) p = rotate_90(p);
  EXPECT_EQ(p, 0b011'010'110);
  EXPECT_EQ(negative(0b000'010'000), 0b111'101'111);
}

TEST(MarkerSelection, HundredTwentyUniquePatternsSixtyPositivesAndTheirNegatives) {
  const std::vector<Pattern> patterns = unique_patterns();
  ASSERT_EQ(patterns.size(), 120u);
  std::set<Pattern> classes;
  for (std::size_t i = 0; i < patterns.size(); ++i) {
    const Pattern p = patterns[i];
    EXPECT_EQ(canonical(p), p);
    classes.insert(canonical(p));
    // Not equal to any of its own turns: the camera can tell which way is up.
    EXPECT_NE(rotate_90(p), p);
    EXPECT_NE(rotate_90(rotate_90(p)), p);
    EXPECT_EQ((p >> 4) & 1, i < 60 ? 0 : 1) << "positives have a white centre";
    if (i < 60) {
      EXPECT_EQ(patterns[i + 60], canonical(negative(p)));
    }
  }
  EXPECT_EQ(classes.size(), 120u) << "one pattern per rotation class";
  // Brute force over all 512: the classes with no symmetry are exactly these.
  std::set<Pattern> expected;
  for (Pattern p = 0; p < 512; ++p) {
    if (rotate_90(rotate_90(p)) != p) expected.insert(canonical(p));
  }
  EXPECT_EQ(classes, expected);
}

TEST(MarkerSelection, SimilarityIsTheFewestDifferingPatchesOverRotations) {
  const Pattern p = 0b001'011'100;
  EXPECT_EQ(similarity(p, rotate_90(p)), 0);
  EXPECT_EQ(similarity(p, p ^ 0b000'000'001), 1);
  // The centre never turns, so a pattern and its negative differ there in every rotation.
  EXPECT_EQ(similarity(p, negative(p)), 3);  // here: 9 in place, 3 at the best turn
  EXPECT_EQ(std::popcount(static_cast<unsigned>(p ^ negative(p))), 9);
  for (Pattern a : {Pattern{3}, Pattern{0b101'001'000}, Pattern{0b011'110'000}}) {
    for (Pattern b : {Pattern{6}, Pattern{0b100'111'001}}) {
      EXPECT_EQ(similarity(a, b), similarity(b, a));
    }
  }
}

TEST(MarkerSelection, TheExhaustiveSearchFindsThePublishedBest) {
  const MarkerSet best = select_markers();
  EXPECT_EQ(best.combinations_searched, 50'063'860);
  EXPECT_EQ(best.min_similarity, 2);
  EXPECT_EQ(best.sum_similarity, 568);
  // Recompute the set's figures from its patterns, independently of the search's bookkeeping.
  const std::vector<Pattern> patterns = unique_patterns();
  int min = 99, sum = 0;
  for (int i = 0; i < 12; ++i) {
    EXPECT_EQ(best.indices[i + (i < 6 ? 6 : -6)], best.indices[i] + (i < 6 ? 60 : -60));
    for (int j = 0; j < 12; ++j) {
      if (i == j) continue;
      const int s = similarity(patterns[best.indices[i]], patterns[best.indices[j]]);
      min = std::min(min, s);
      sum += s;
    }
  }
  EXPECT_EQ(min, 2);
  EXPECT_EQ(sum, 568);
}

}  // namespace
}  // namespace ultrasim::tracking
