#include "ultrasim/tracking/marker_selection.hpp"

#include <algorithm>
#include <bit>
#include <limits>

namespace ultrasim::tracking {

namespace {

constexpr int kPositives = 60;
constexpr int kChosen = 6;
constexpr Pattern kAllPatches = 0x1FF;
constexpr Pattern kCentre = 1u << 4;

int patch(Pattern p, int row, int col) {
  return (p >> (row * 3 + col)) & 1;
}

}  // namespace

Pattern rotate_90(Pattern p) {
  // Clockwise: the new (r, c) is the old (2 − c, r).
  Pattern out = 0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out |= static_cast<Pattern>(patch(p, 2 - c, r) << (r * 3 + c));
  }
  return out;
}

Pattern canonical(Pattern p) {
  Pattern best = p;
  for (int turn = 1; turn < 4; ++turn) {
    p = rotate_90(p);
    best = std::min(best, p);
  }
  return best;
}

Pattern negative(Pattern p) {
  return static_cast<Pattern>(~p & kAllPatches);
}

std::vector<Pattern> unique_patterns() {
  std::vector<Pattern> positives;
  for (Pattern p = 0; p <= kAllPatches; ++p) {
    if ((p & kCentre) != 0 || canonical(p) != p) continue;
    // A 180° turn maps the pattern onto itself for every symmetric one (a 90° symmetry implies
    // it): those are ambiguous.
    if (rotate_90(rotate_90(p)) == p) continue;
    positives.push_back(p);
  }
  std::vector<Pattern> all = positives;
  for (Pattern p : positives) all.push_back(canonical(negative(p)));
  return all;
}

int similarity(Pattern a, Pattern b) {
  int best = std::numeric_limits<int>::max();
  for (int turn = 0; turn < 4; ++turn) {
    best = std::min(best, std::popcount(static_cast<unsigned>(a ^ b)));
    b = rotate_90(b);
  }
  return best;
}

MarkerSet select_markers() {
  const std::vector<Pattern> patterns = unique_patterns();
  // A positive and its negative go together: per pair of positives (a, b), the four
  // similarities between {a, −a} and {b, −b}; per positive, its similarity to its negative.
  struct Cross {
    int min;
    int sum;
  };
  std::array<std::array<Cross, kPositives>, kPositives> cross{};
  std::array<int, kPositives> own{};
  for (int a = 0; a < kPositives; ++a) {
    own[a] = similarity(patterns[a], patterns[a + kPositives]);
    for (int b = 0; b < kPositives; ++b) {
      const int s[4] = {similarity(patterns[a], patterns[b]),
                        similarity(patterns[a], patterns[b + kPositives]),
                        similarity(patterns[a + kPositives], patterns[b]),
                        similarity(patterns[a + kPositives], patterns[b + kPositives])};
      cross[a][b] = {std::min({s[0], s[1], s[2], s[3]}), s[0] + s[1] + s[2] + s[3]};
    }
  }
  MarkerSet best;
  best.min_similarity = -1;
  std::array<int, kChosen> chosen{};
  std::array<int, kChosen + 1> min_at{}, sum_at{};  // running values after `depth` choices
  min_at[0] = std::numeric_limits<int>::max();
  // Depth-first over increasing positives; each new one adds its pair's own similarity (twice:
  // both triangles) and its crossings with those already chosen.
  auto search = [&](auto&& self, int depth, int first) -> void {
    if (depth == kChosen) {
      ++best.combinations_searched;
      if (min_at[depth] > best.min_similarity ||
          (min_at[depth] == best.min_similarity && sum_at[depth] > best.sum_similarity)) {
        best.min_similarity = min_at[depth];
        best.sum_similarity = sum_at[depth];
        for (int i = 0; i < kChosen; ++i) {
          best.indices[i] = chosen[i];
          best.indices[i + kChosen] = chosen[i] + kPositives;
        }
      }
      return;
    }
    for (int p = first; p <= kPositives - (kChosen - depth); ++p) {
      int m = std::min(min_at[depth], own[p]);
      int s = sum_at[depth] + 2 * own[p];
      for (int i = 0; i < depth; ++i) {
        m = std::min(m, cross[chosen[i]][p].min);
        s += 2 * cross[chosen[i]][p].sum;
      }
      chosen[depth] = p;
      min_at[depth + 1] = m;
      sum_at[depth + 1] = s;
      self(self, depth + 1, p + 1);
    }
  };
  search(search, 0, 0);
  return best;
}

}  // namespace ultrasim::tracking
