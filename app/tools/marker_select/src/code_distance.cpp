#include "ultrasim/tools/code_distance.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <stdexcept>
#include <vector>

namespace ultrasim::tools {

int min_distance_under_rotation(const CodeFamily& family) {
  const auto nbits = static_cast<int>(family.bit_x.size());
  if (nbits == 0 || nbits > 64 || family.bit_y.size() != family.bit_x.size()) {
    throw std::invalid_argument("min_distance_under_rotation: bad layout");
  }
  // Turning the tag 90° about its centre moves the patch at (x, y) to (lo + hi − y, x), with lo
  // and hi the layout's extreme coordinates; as a permutation of bit indices. Coordinates are
  // signed (AprilTag's newer layouts put their outer ring at negative ones, stored as uint32).
  auto x_of = [&](int i) { return static_cast<std::int32_t>(family.bit_x[i]); };
  auto y_of = [&](int i) { return static_cast<std::int32_t>(family.bit_y[i]); };
  std::int32_t lo = std::numeric_limits<std::int32_t>::max();
  std::int32_t hi = std::numeric_limits<std::int32_t>::min();
  for (int i = 0; i < nbits; ++i) {
    lo = std::min({lo, x_of(i), y_of(i)});
    hi = std::max({hi, x_of(i), y_of(i)});
  }
  std::vector<int> turned(static_cast<std::size_t>(nbits));
  for (int i = 0; i < nbits; ++i) {
    const std::int32_t x = lo + hi - y_of(i), y = x_of(i);
    int j = 0;
    while (j < nbits && !(x_of(j) == x && y_of(j) == y)) ++j;
    if (j == nbits) {
      throw std::invalid_argument("min_distance_under_rotation: a turned patch is off the layout");
    }
    turned[static_cast<std::size_t>(i)] = j;
  }
  auto rotate = [&](std::uint64_t code) {
    std::uint64_t out = 0;
    for (int i = 0; i < nbits; ++i) {
      if ((code >> (nbits - 1 - i) & 1u) != 0) out |= std::uint64_t{1} << (nbits - 1 - turned[i]);
    }
    return out;
  };
  const std::size_t n = family.codes.size();
  std::vector<std::array<std::uint64_t, 4>> turns(n);
  for (std::size_t c = 0; c < n; ++c) {
    turns[c][0] = family.codes[c];
    for (int r = 1; r < 4; ++r) turns[c][r] = rotate(turns[c][r - 1]);
  }
  int best = nbits;
  for (std::size_t a = 0; a < n; ++a) {
    for (int r = 1; r < 4; ++r) {
      best = std::min(best, std::popcount(turns[a][0] ^ turns[a][r]));
    }
    for (std::size_t b = a + 1; b < n; ++b) {
      for (int r = 0; r < 4; ++r) {
        best = std::min(best, std::popcount(turns[a][0] ^ turns[b][r]));
      }
    }
  }
  return best;
}

}  // namespace ultrasim::tools
