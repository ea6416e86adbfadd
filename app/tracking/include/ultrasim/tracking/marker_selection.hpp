#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace ultrasim::tracking {

// The published marker selection for the camera dodecahedron (dissertation, appendix D): twelve
// 3×3 binary patterns, one per face, that differ from each other as much as possible.
//
// A pattern is 9 bits, bit r·3+c for row r, column c (row 0 on top). A camera sees a marker in
// any of four rotations, so a pattern equal to one of its own rotations is ambiguous (which way
// is up?), and patterns that are rotations of each other are one marker. Of the 512 patterns,
// 120 are unique: not symmetric under any rotation, one per rotation class.

using Pattern = std::uint16_t;  // low 9 bits

// The pattern turned 90° clockwise.
Pattern rotate_90(Pattern p);
// The smallest of the pattern's four rotations: one name per rotation class.
Pattern canonical(Pattern p);
// The pattern with every patch inverted (black ↔ white).
Pattern negative(Pattern p);

// The 120 unique patterns in the published order: 60 positives (centre patch white, i.e. bit 4
// clear), then their negatives in the same order, so pattern i + 60 is the negative of i. Each as
// its canonical rotation, positives in increasing order.
std::vector<Pattern> unique_patterns();

// The published similarity: the fewest patches in which `a` differs from any rotation of `b`
// (0: the same marker). Symmetric.
int similarity(Pattern a, Pattern b);

struct MarkerSet {
  std::array<int, 12> indices{};  // into unique_patterns(): six positives, then their negatives
  int min_similarity = 0;         // the smallest similarity between two of the twelve
  int sum_similarity = 0;         // over the 12×12 matrix (both triangles)
  std::int64_t combinations_searched = 0;
};

// Searches every choice of six positives, C(60, 6) = 50,063,860 of them, each with its six
// negatives, for the largest minimum similarity and, among those, the largest sum. The first
// best found in lexicographic order of the positives is returned.
MarkerSet select_markers();

}  // namespace ultrasim::tracking
