#include "ultrasim/sim/node_block_matrix.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace ultrasim::sim::detail {

NodeBlockMatrix::NodeBlockMatrix(const Eigen::SparseMatrix<double, Eigen::RowMajor>& k, int bands) {
  if (bands < 1) {
    throw std::invalid_argument("NodeBlockMatrix: " + std::to_string(bands) + " bands");
  }
  if (k.rows() != k.cols() || k.rows() % 3 != 0) {
    throw std::invalid_argument("NodeBlockMatrix: " + std::to_string(k.rows()) + " × " +
                                std::to_string(k.cols()) +
                                " is not a square matrix of 3 × 3 blocks");
  }
  const auto nodes = static_cast<int>(k.rows() / 3);
  row_begin_.reserve(static_cast<std::size_t>(nodes) + 1);
  row_begin_.push_back(0);
  std::vector<int> columns;
  for (int node = 0; node < nodes; ++node) {
    columns.assign(1, node);  // the diagonal block first, stored even if K leaves it empty
    for (int r = 0; r < 3; ++r) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(k, 3 * node + r); it;
           ++it) {
        if (it.col() / 3 > node) columns.push_back(static_cast<int>(it.col() / 3));
      }
    }
    std::sort(columns.begin() + 1, columns.end());
    columns.erase(std::unique(columns.begin(), columns.end()), columns.end());
    const std::size_t first = values_.size();
    values_.resize(first + 9 * columns.size(), 0.0);
    for (int r = 0; r < 3; ++r) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(k, 3 * node + r); it;
           ++it) {
        const auto column_node = static_cast<int>(it.col() / 3);
        if (column_node < node) continue;
        const auto block = column_node == node
                               ? 0
                               : std::lower_bound(columns.begin() + 1, columns.end(), column_node) -
                                     columns.begin();
        values_[first + 9 * static_cast<std::size_t>(block) + 3 * r + it.col() % 3] = it.value();
      }
    }
    block_column_.insert(block_column_.end(), columns.begin(), columns.end());
    row_begin_.push_back(static_cast<int>(block_column_.size()));
  }
  for (int band = 0; band <= bands; ++band) {
    band_begin_.push_back(static_cast<int>(static_cast<long>(nodes) * band / bands));
  }
  for (int band = 0; band < bands; ++band) {
    int end = band_begin_[band + 1];
    for (int i = band_begin_[band]; i < band_begin_[band + 1]; ++i) {
      for (int b = row_begin_[i]; b < row_begin_[i + 1]; ++b)
        end = std::max(end, block_column_[b] + 1);
    }
    spill_end_.push_back(end);
  }
}

void NodeBlockMatrix::times_band(int band, const Eigen::VectorXd& x, const Eigen::VectorXd* d,
                                 Eigen::VectorXd& y, Eigen::VectorXd& spill) const {
  const int begin = band_begin_[band];
  const int end = band_begin_[band + 1];
  spill.setZero(spill_rows(band));
  y.segment(3 * begin, 3 * (end - begin)).setZero();
  const double* xs = x.data();
  double* ys = y.data();
  for (int i = begin; i < end; ++i) {
    const double* xi = xs + 3 * static_cast<std::size_t>(i);
    const double* m = values_.data() + 9 * static_cast<std::size_t>(row_begin_[i]);
    // Row i: its diagonal block, then each upper block B_ij x_j; column j gets B_ijᵀ x_i.
    double y0 = m[0] * xi[0] + m[1] * xi[1] + m[2] * xi[2];
    double y1 = m[3] * xi[0] + m[4] * xi[1] + m[5] * xi[2];
    double y2 = m[6] * xi[0] + m[7] * xi[1] + m[8] * xi[2];
    for (int b = row_begin_[i] + 1; b < row_begin_[i + 1]; ++b) {
      m = values_.data() + 9 * static_cast<std::size_t>(b);
      const int j = block_column_[b];
      const double* xj = xs + 3 * static_cast<std::size_t>(j);
      y0 += m[0] * xj[0] + m[1] * xj[1] + m[2] * xj[2];
      y1 += m[3] * xj[0] + m[4] * xj[1] + m[5] * xj[2];
      y2 += m[6] * xj[0] + m[7] * xj[1] + m[8] * xj[2];
      double* yj = j < end ? ys + 3 * static_cast<std::size_t>(j)
                           : spill.data() + 3 * static_cast<std::size_t>(j - end);
      yj[0] += m[0] * xi[0] + m[3] * xi[1] + m[6] * xi[2];
      yj[1] += m[1] * xi[0] + m[4] * xi[1] + m[7] * xi[2];
      yj[2] += m[2] * xi[0] + m[5] * xi[1] + m[8] * xi[2];
    }
    if (d != nullptr) {
      const double* di = d->data() + 3 * static_cast<std::size_t>(i);
      y0 += di[0] * xi[0];
      y1 += di[1] * xi[1];
      y2 += di[2] * xi[2];
    }
    double* yi = ys + 3 * static_cast<std::size_t>(i);
    yi[0] += y0;
    yi[1] += y1;
    yi[2] += y2;
  }
}

void NodeBlockMatrix::add_spills(const std::vector<Eigen::VectorXd>& spills,
                                 Eigen::VectorXd& y) const {
  for (int band = 0; band < bands(); ++band) {
    y.segment(3 * band_begin_[band + 1], spill_rows(band)) += spills[band];
  }
}

}  // namespace ultrasim::sim::detail
