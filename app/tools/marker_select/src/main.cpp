// ultrasim-marker-select: the published marker selection for the camera dodecahedron, run in
// full (C(60, 6) sets of 3×3 patterns), and the worst case of the AprilTag families we use, for
// comparison.

#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

#include <chrono>
#include <cstdio>

#include "ultrasim/tools/code_distance.hpp"
#include "ultrasim/tracking/marker_selection.hpp"

namespace {

using namespace ultrasim;

int family_distance(apriltag_family_t* family) {
  const tools::CodeFamily f{{family->codes, family->ncodes},
                            {family->bit_x, family->nbits},
                            {family->bit_y, family->nbits}};
  return tools::min_distance_under_rotation(f);
}

}  // namespace

int main() {
  const auto start = std::chrono::steady_clock::now();
  const tracking::MarkerSet best = tracking::select_markers();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto patterns = tracking::unique_patterns();
  std::printf("searched %lld sets of six positives (with their negatives) in %.2f s\n",
              static_cast<long long>(best.combinations_searched), seconds);
  std::printf("best: smallest similarity %d patches, sum %d (published: 2 and 568)\n",
              best.min_similarity, best.sum_similarity);
  std::printf("indices (0-59 positives, +60 their negatives):");
  for (int i : best.indices) std::printf(" %d", i);
  std::printf("\npatterns (# black, . white), one per dodecahedron face:\n");
  for (int row = 0; row < 3; ++row) {
    for (int i : best.indices) {
      for (int col = 0; col < 3; ++col) {
        std::putchar(((patterns[static_cast<std::size_t>(i)] >> (row * 3 + col)) & 1) != 0 ? '#'
                                                                                           : '.');
      }
      std::putchar(' ');
    }
    std::putchar('\n');
  }
  apriltag_family_t* t36 = tag36h11_create();
  apriltag_family_t* t41 = tagStandard41h12_create();
  std::printf(
      "worst case (fewest differing bits, any rotation): 3x3 markers %d of 9 bits; "
      "tag36h11 %d of 36 (%u codes); tagStandard41h12 %d of 41 (%u codes)\n",
      best.min_similarity, family_distance(t36), t36->ncodes, family_distance(t41), t41->ncodes);
  tag36h11_destroy(t36);
  tagStandard41h12_destroy(t41);
  return 0;
}
