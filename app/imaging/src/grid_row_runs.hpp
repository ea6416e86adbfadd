#pragma once

#include <span>
#include <vector>

#include "ultrasim/imaging/bscan.hpp"

namespace ultrasim::imaging {

// Columns [col_begin, col_end) of one image row that the grid maps into the probe plane.
struct PixelRun {
  int col_begin = 0;
  int col_end = 0;
};

// Which pixels of each row a grid samples, as runs: every pixel for a linear grid, the pixels
// inside the sector for a convex one. Built with BscanGrid::pixel_to_plane_mm itself, so the mask
// is exactly the reference's, and the slicers skip its polar test per pixel and frame. Private
// to the slicers.
class GridRowRuns {
 public:
  // Recomputes the runs for a grid: width × height calls of pixel_to_plane_mm. Allocates; call
  // when the grid changes, not per frame.
  void assign(const BscanGrid& grid);

  // Runs of row `row`, left to right. Read-only; safe from many threads.
  std::span<const PixelRun> row(int row) const {
    return std::span<const PixelRun>(runs_).subspan(row_start_[row],
                                                    row_start_[row + 1] - row_start_[row]);
  }

 private:
  std::vector<int> row_start_;  // per row + 1: offset of its first run in runs_
  std::vector<PixelRun> runs_;
};

}  // namespace ultrasim::imaging
