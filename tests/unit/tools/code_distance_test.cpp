// The worst-case distance of a fiducial family under rotation, against the distance AprilTag's
// own families declare (their "h") and against the marker search's own similarity.

#include "ultrasim/tools/code_distance.hpp"

#include <apriltag/tag16h5.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>
#include <gtest/gtest.h>

#include <vector>

#include "ultrasim/tracking/marker_selection.hpp"

namespace ultrasim::tools {
namespace {

int distance_of(apriltag_family_t* family) {
  return min_distance_under_rotation({{family->codes, family->ncodes},
                                      {family->bit_x, family->nbits},
                                      {family->bit_y, family->nbits}});
}

TEST(CodeDistance, AprilTagFamiliesHaveTheDistanceTheyDeclare) {
  apriltag_family_t* t16 = tag16h5_create();
  apriltag_family_t* t36 = tag36h11_create();
  apriltag_family_t* t41 = tagStandard41h12_create();  // its outer ring at negative coordinates
  EXPECT_EQ(distance_of(t16), static_cast<int>(t16->h));
  EXPECT_EQ(distance_of(t36), static_cast<int>(t36->h));
  EXPECT_EQ(distance_of(t41), static_cast<int>(t41->h));
  EXPECT_EQ(t36->h, 11u);
  EXPECT_EQ(t41->h, 12u);
  tag16h5_destroy(t16);
  tag36h11_destroy(t36);
  tagStandard41h12_destroy(t41);
}

TEST(CodeDistance, TheSelectedMarkersWorstCaseAgreesWithTheSearch) {
  const tracking::MarkerSet best = tracking::select_markers();
  const auto patterns = tracking::unique_patterns();
  // Patch (col, row) is pattern bit row·3 + col; as a family, bit (8 − i) is layout entry i.
  std::vector<std::uint32_t> xs, ys;
  for (std::uint32_t i = 0; i < 9; ++i) {
    xs.push_back(i % 3);
    ys.push_back(i / 3);
  }
  std::vector<std::uint64_t> codes;
  for (int index : best.indices) {
    std::uint64_t code = 0;
    for (int i = 0; i < 9; ++i) {
      if ((patterns[static_cast<std::size_t>(index)] >> i & 1) != 0) code |= 1u << (8 - i);
    }
    codes.push_back(code);
  }
  EXPECT_EQ(min_distance_under_rotation({codes, xs, ys}), best.min_similarity);
  EXPECT_EQ(best.min_similarity, 2);
}

}  // namespace
}  // namespace ultrasim::tools
