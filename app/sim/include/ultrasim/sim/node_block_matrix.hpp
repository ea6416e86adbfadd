#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

namespace ultrasim::sim::detail {

// A symmetric 3n × 3n sparse matrix (a stiffness K) stored as its upper triangle's 3 × 3 blocks
// between nodes: one column index per block instead of one per entry, and each off-diagonal block
// read once for both its row and its column. The PCG FEM's CG spends most of its time in
// y = K x, which streams K from memory: on a 15³-node sub-volume this form holds 1.6 MB against
// Eigen's 4.3 MB of compressed rows (it fits a core's L2 cache here), docs/benchmarks.md.
//
// y = K x is computed in bands of node rows, fixed when the matrix is built, so that the sum is
// the same to the last bit whatever threads run them: times_band() for every band (any order, in
// parallel), then add_spills(). A band writes its own rows and, for rows past its end, a spill
// the caller keeps per band.
class NodeBlockMatrix {
 public:
  NodeBlockMatrix() = default;
  // From the upper triangle of k (its lower triangle is not read), in `bands` bands; throws
  // std::invalid_argument for a matrix that is not square or not made of 3 × 3 blocks, or fewer
  // than one band.
  NodeBlockMatrix(const Eigen::SparseMatrix<double, Eigen::RowMajor>& k, int bands);

  int block_rows() const { return static_cast<int>(row_begin_.size()) - 1; }
  int bands() const { return static_cast<int>(spill_end_.size()); }
  int stored_blocks() const { return static_cast<int>(block_column_.size()); }
  // Rows of K x the given band's spill holds (past the band's last row).
  int spill_rows(int band) const { return 3 * (spill_end_[band] - band_begin_[band + 1]); }

  // y's rows in `band` = those rows of (K + diag(d)) x, less what later add_spills() adds; `spill`
  // (resized to spill_rows(band)) = the band's share of the rows past it. d may be null.
  void times_band(int band, const Eigen::VectorXd& x, const Eigen::VectorXd* d, Eigen::VectorXd& y,
                  Eigen::VectorXd& spill) const;
  // y += every band's spill, in band order.
  void add_spills(const std::vector<Eigen::VectorXd>& spills, Eigen::VectorXd& y) const;

 private:
  std::vector<int> row_begin_;     // per node row, its first block (the diagonal); one past the end
  std::vector<int> block_column_;  // per block, its node column (≥ its row)
  std::vector<double> values_;     // per block, 9 values row by row
  std::vector<int> band_begin_;    // bands + 1 node rows
  std::vector<int> spill_end_;     // per band, one past the last node row it reaches
};

}  // namespace ultrasim::sim::detail
