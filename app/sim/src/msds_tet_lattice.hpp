#pragma once

// Counting inverted tets fast (internal to MsdsEngine): the explicit engine counts them every few
// steps, and one by one that costs as much as a third of the steps.
//
// A tet (n0, n1, n2, n3) has the offset pattern (n0 − m, n1 − m, n2 − m, n3 − m), m its lowest
// node, as springs lie on diagonals (msds_spring_lattice.hpp). On a grid mesh a few patterns hold
// every tet (10 for the 5-tet grid), and along one pattern the tets of consecutive m read
// consecutive positions: AVX2 evaluates four at a time with plain loads. A pattern keeps one slot
// per m (a bit says whether a tet is there); sparse patterns' tets are counted one by one. Every
// tet's signed volume is (n1 − n0) × (n2 − n0) · (n3 − n0) in double, the same operations as
// geometry::signed_tet_volume (up to its / 6), so the count is exact: the layout changes the
// speed, not the answer.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::sim::msds_detail {

// (n1 − n0) × (n2 − n0) · (n3 − n0): six times geometry::signed_tet_volume (the same operations),
// from positions stored one array per coordinate.
double six_signed_volume(const double* x, const double* y, const double* z, const geometry::Tet& t);

class TetLattice {
 public:
  // A pattern is kept dense when at least this fraction of its slots hold a tet.
  static constexpr double kMinPatternFill = 0.25;

  // Allocates. node_count: the positions the counts read hold node_count + kNodePadding entries.
  TetLattice(std::span<const geometry::Tet> tets, int node_count);

  // The work splits into chunk_count() independent chunks; count(chunk) is the number of tets
  // in chunk `chunk` with a signed volume ≤ 0 at positions (x, y, z) (mm, one array per
  // coordinate). Any chunks, in any order, on any threads: the sum is the same.
  int chunk_count() const { return static_cast<int>(chunks_.size()); }
  int count(int chunk, const double* x, const double* y, const double* z) const;

  int pattern_count() const { return static_cast<int>(patterns_.size()); }
  int loose_tet_count() const { return static_cast<int>(loose_.size()); }

 private:
  struct Pattern {
    std::array<int, 4> offsets{};  // node k of the tet in slot m is m + offsets[k]
    int slot_count = 0;
    // Bit l of [g]: slot 4 g + l holds a tet.
    std::vector<std::uint8_t> occupied;
  };
  // A piece of work: slots [first, last) of one pattern, or loose tets [first, last).
  struct Chunk {
    int pattern = -1;  // -1: loose tets
    int first = 0;
    int last = 0;
  };

  std::vector<Pattern> patterns_;
  std::vector<geometry::Tet> loose_;
  std::vector<Chunk> chunks_;
  bool use_avx2_ = false;
};

}  // namespace ultrasim::sim::msds_detail
