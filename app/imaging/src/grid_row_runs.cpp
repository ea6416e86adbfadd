#include "grid_row_runs.hpp"

namespace ultrasim::imaging {

void GridRowRuns::assign(const BscanGrid& grid) {
  row_start_.assign(static_cast<std::size_t>(grid.height_px()) + 1, 0);
  runs_.clear();
  for (int row = 0; row < grid.height_px(); ++row) {
    row_start_[row] = static_cast<int>(runs_.size());
    int begin = -1;
    for (int col = 0; col <= grid.width_px(); ++col) {
      const bool inside = col < grid.width_px() && grid.pixel_to_plane_mm(col, row).has_value();
      if (inside && begin < 0) begin = col;
      if (!inside && begin >= 0) {
        runs_.push_back({begin, col});
        begin = -1;
      }
    }
  }
  row_start_[grid.height_px()] = static_cast<int>(runs_.size());
}

}  // namespace ultrasim::imaging
