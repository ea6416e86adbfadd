#include "ultrasim/sim/coarse_correction.hpp"

#include <algorithm>
#include <set>
#include <stdexcept>

namespace ultrasim::sim {

namespace {

// Per axis, the coarse grid's nodes in grid-node units: both ends of the grid and the middle of
// each overlap band, where two sub-volumes' anchors meet.
std::vector<double> coarse_points(std::span<const SubVolumeBox> boxes, int axis, int grid_nodes) {
  std::set<int> firsts, lasts;
  for (const auto& b : boxes) {
    firsts.insert(b.first_node[axis]);
    lasts.insert(b.first_node[axis] + b.nodes[axis] - 1);
  }
  std::vector<double> points{0.0};
  auto last = lasts.begin();
  for (auto first = std::next(firsts.begin()); first != firsts.end(); ++first, ++last) {
    points.push_back(0.5 * (*first + *last));
  }
  points.push_back(grid_nodes - 1.0);
  return points;
}

}  // namespace

CoarseCorrection::CoarseCorrection(const geometry::GridSpec& grid,
                                   std::span<const SubVolumeBox> boxes,
                                   std::span<const DeformationEngine* const> engines) {
  if (boxes.size() != engines.size()) {
    throw std::invalid_argument("CoarseCorrection: " + std::to_string(boxes.size()) +
                                " boxes for " + std::to_string(engines.size()) + " engines");
  }
  for (int a = 0; a < 3; ++a) {
    const std::vector<double> points = coarse_points(boxes, a, grid.nodes[a]);
    nodes_[a] = static_cast<int>(points.size());
    interval_[a].resize(grid.nodes[a]);
    upper_weight_[a].resize(grid.nodes[a]);
    for (int i = 0, k = 0; i < grid.nodes[a]; ++i) {
      while (k + 2 < nodes_[a] && i > points[k + 1]) ++k;
      interval_[a][i] = k;
      upper_weight_[a][i] = (i - points[k]) / (points[k + 1] - points[k]);
    }
  }
  const int dofs = 3 * coarse_node_count();
  rest_stiffness_ = Eigen::MatrixXd::Zero(dofs, dofs);
  subs_.resize(boxes.size());
  for (std::size_t s = 0; s < boxes.size(); ++s) {
    Sub& sub = subs_[s];
    const SubVolumeBox& box = boxes[s];
    sub.first_node = box.first_node;
    sub.nodes = box.nodes;
    const Eigen::Vector3i last = box.first_node + box.nodes - Eigen::Vector3i::Ones();
    for (int a = 0; a < 3; ++a) {
      sub.coarse_first[a] = interval_[a][box.first_node[a]];
      sub.coarse_nodes[a] = interval_[a][last[a]] + 2 - sub.coarse_first[a];
    }
    const int local_dofs = 3 * sub.coarse_nodes.prod();
    const int n = box.node_count();
    sub.stiffness = engines[s]->rest_stiffness_mn_per_mm();
    if (sub.stiffness.rows() != 3 * n) {
      throw std::invalid_argument("CoarseCorrection: an engine's stiffness does not fit its box");
    }
    sub.fixed.resize(n);
    for (int l = 0; l < n; ++l) sub.fixed[l] = engines[s]->holds_node(l) ? 1 : 0;
    sub.held = sub.fixed;
    sub.held_free.reserve(n);
    sub.residual = Eigen::VectorXd::Zero(local_dofs);
    sub.seam_residual = Eigen::VectorXd::Zero(local_dofs);
    sub.correction = Eigen::VectorXd::Zero(local_dofs);
    sub.row = Eigen::VectorXd::Zero(local_dofs);
    sub.forces = Eigen::VectorXd::Zero(3 * n);
    sub.move = Eigen::VectorXd::Zero(3 * n);
    sub.weights.resize(n);
    for (int l = 0; l < n; ++l) sub.weights[l] = local_weights(sub, l);
    build_rest_coarse_stiffness(sub);
    sub.coarse_stiffness = sub.rest_coarse_stiffness;
    for (int i = 0; i < local_dofs; ++i) {
      for (int j = 0; j < local_dofs; ++j) {
        rest_stiffness_(global_dof(sub, i), global_dof(sub, j)) += sub.rest_coarse_stiffness(i, j);
      }
    }
  }
  stiffness_ = rest_stiffness_;
  seam_stiffness_ = Eigen::MatrixXd::Zero(dofs, dofs);
  residual_ = Eigen::VectorXd::Zero(dofs);
  correction_ = Eigen::VectorXd::Zero(dofs);
  factor_ = Eigen::LLT<Eigen::MatrixXd>(dofs);
}

CoarseCorrection::Weights CoarseCorrection::weights(const Eigen::Vector3i& g) const {
  Weights w;
  for (int b = 0; b < 8; ++b) {
    int index = 0, stride = 1;
    double weight = 1.0;
    for (int a = 0; a < 3; ++a) {
      const bool upper = (b >> a) & 1;
      const double u = upper_weight_[a][g[a]];
      index += stride * (interval_[a][g[a]] + upper);
      weight *= upper ? u : 1.0 - u;
      stride *= nodes_[a];
    }
    w.coarse[b] = index;
    w.weight[b] = weight;
  }
  return w;
}

CoarseCorrection::Weights CoarseCorrection::local_weights(const Sub& sub, int l) const {
  const Eigen::Vector3i local(l % sub.nodes.x(), (l / sub.nodes.x()) % sub.nodes.y(),
                              l / (sub.nodes.x() * sub.nodes.y()));
  Weights w = weights(sub.first_node + local);
  for (int& c : w.coarse) c = local_dof(sub, c, 0) / 3;
  return w;
}

int CoarseCorrection::local_dof(const Sub& sub, int coarse_node, int d) const {
  const int x = coarse_node % nodes_.x() - sub.coarse_first.x();
  const int y = (coarse_node / nodes_.x()) % nodes_.y() - sub.coarse_first.y();
  const int z = coarse_node / (nodes_.x() * nodes_.y()) - sub.coarse_first.z();
  return 3 * (x + sub.coarse_nodes.x() * (y + sub.coarse_nodes.y() * z)) + d;
}

int CoarseCorrection::global_dof(const Sub& sub, int local) const {
  const int node = local / 3;
  const int x = node % sub.coarse_nodes.x() + sub.coarse_first.x();
  const int y = (node / sub.coarse_nodes.x()) % sub.coarse_nodes.y() + sub.coarse_first.y();
  const int z = node / (sub.coarse_nodes.x() * sub.coarse_nodes.y()) + sub.coarse_first.z();
  return 3 * (x + nodes_.x() * (y + nodes_.y() * z)) + local % 3;
}

void CoarseCorrection::build_rest_coarse_stiffness(Sub& sub) const {
  // Pᵀ K P row by row of K: row r of K P, then its outer product with row r of P.
  const int n = static_cast<int>(sub.fixed.size());
  const std::vector<Weights>& w = sub.weights;
  sub.rest_coarse_stiffness = Eigen::MatrixXd::Zero(sub.row.size(), sub.row.size());
  for (int r = 0; r < 3 * n; ++r) {
    if (sub.fixed[r / 3]) continue;
    sub.row.setZero();
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(sub.stiffness, r); it;
         ++it) {
      const int j = static_cast<int>(it.col());
      if (sub.fixed[j / 3]) continue;
      for (int b = 0; b < 8; ++b)
        sub.row[3 * w[j / 3].coarse[b] + j % 3] += it.value() * w[j / 3].weight[b];
    }
    for (int a = 0; a < 8; ++a) {
      sub.rest_coarse_stiffness.row(3 * w[r / 3].coarse[a] + r % 3) +=
          w[r / 3].weight[a] * sub.row.transpose();
    }
  }
}

void CoarseCorrection::update_held_coarse_stiffness(Sub& sub) const {
  // Pᵀ D K D P = Pᵀ K P − Σ_h (p_h g_hᵀ + g_h p_hᵀ) + Σ_{h,h'} K_hh' p_h p_h'ᵀ over the held
  // rows h (p_h: row h of P; g_h: row h of K P): the rows the probe holds, not the whole K.
  sub.coarse_stiffness = sub.rest_coarse_stiffness;
  for (int node : sub.held_free) {
    const Weights& wn = sub.weights[node];
    for (int d = 0; d < 3; ++d) {
      const int r = 3 * node + d;
      sub.row.setZero();
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(sub.stiffness, r); it;
           ++it) {
        const int j = static_cast<int>(it.col());
        if (sub.fixed[j / 3]) continue;
        const Weights& wj = sub.weights[j / 3];
        for (int b = 0; b < 8; ++b) sub.row[3 * wj.coarse[b] + j % 3] += it.value() * wj.weight[b];
        if (!sub.held[j / 3]) continue;
        for (int a = 0; a < 8; ++a) {
          for (int b = 0; b < 8; ++b) {
            sub.coarse_stiffness(3 * wn.coarse[a] + d, 3 * wj.coarse[b] + j % 3) +=
                it.value() * wn.weight[a] * wj.weight[b];
          }
        }
      }
      for (int a = 0; a < 8; ++a) {
        const int c = 3 * wn.coarse[a] + d;
        sub.coarse_stiffness.row(c) -= wn.weight[a] * sub.row.transpose();
        sub.coarse_stiffness.col(c) -= wn.weight[a] * sub.row;
      }
    }
  }
}

void CoarseCorrection::update(int s, const DeformationEngine& engine) {
  Sub& sub = subs_[s];
  const int n = static_cast<int>(sub.fixed.size());
  sub.held_free.clear();
  for (int l = 0; l < n; ++l) {
    sub.held[l] = sub.fixed[l] || engine.holds_node(l);
    if (sub.held[l] && !sub.fixed[l]) sub.held_free.push_back(l);
  }
  if (!sub.held_free.empty()) update_held_coarse_stiffness(sub);
  engine.tissue_forces_mn(sub.forces);
  sub.residual.setZero();
  for (int l = 0; l < n; ++l) {
    if (sub.held[l]) continue;
    const Weights& w = sub.weights[l];
    for (int a = 0; a < 8; ++a) {
      sub.residual.segment<3>(3 * w.coarse[a]) += w.weight[a] * sub.forces.segment<3>(3 * l);
    }
  }
}

void CoarseCorrection::add_seam_force(int s, int local_node, const Eigen::Vector3d& force_mn) {
  Sub& sub = subs_[s];
  if (sub.held[local_node]) return;
  const Weights& w = sub.weights[local_node];
  for (int a = 0; a < 8; ++a)
    sub.seam_residual.segment<3>(3 * w.coarse[a]) += w.weight[a] * force_mn;
}

void CoarseCorrection::add_uneven_seam(const Eigen::Vector3i& grid_node,
                                       double stiffness_mn_per_mm) {
  const Weights w = weights(grid_node);
  for (int a = 0; a < 8; ++a) {
    for (int b = 0; b < 8; ++b) {
      const double k = stiffness_mn_per_mm * w.weight[a] * w.weight[b];
      for (int d = 0; d < 3; ++d) seam_stiffness_(3 * w.coarse[a] + d, 3 * w.coarse[b] + d) += k;
    }
  }
}

bool CoarseCorrection::solve() {
  stiffness_ = rest_stiffness_ + seam_stiffness_;
  seam_stiffness_.setZero();
  residual_.setZero();
  for (const Sub& sub : subs_) {
    const auto local_dofs = static_cast<int>(sub.residual.size());
    for (int i = 0; i < local_dofs; ++i) {
      const int gi = global_dof(sub, i);
      residual_[gi] += sub.residual[i] + sub.seam_residual[i];
      if (sub.held_free.empty()) continue;
      for (int j = 0; j < local_dofs; ++j) {
        stiffness_(gi, global_dof(sub, j)) +=
            sub.coarse_stiffness(i, j) - sub.rest_coarse_stiffness(i, j);
      }
    }
  }
  // A coarse node whose every fine node is fixed or held has no stiffness and no residual.
  const double floor = 1e-12 * stiffness_.diagonal().maxCoeff();
  for (Eigen::Index i = 0; i < stiffness_.rows(); ++i) {
    if (!(stiffness_(i, i) > floor)) stiffness_(i, i) = 1.0;
  }
  factor_.compute(stiffness_);
  if (factor_.info() != Eigen::Success) {
    correction_.setZero();
  } else {
    correction_ = factor_.solve(residual_);
  }
  if (!correction_.allFinite()) correction_.setZero();
  for (Sub& sub : subs_) {
    sub.seam_residual.setZero();
    for (Eigen::Index i = 0; i < sub.correction.size(); ++i) {
      sub.correction[i] = correction_[global_dof(sub, static_cast<int>(i))];
    }
  }
  return factor_.info() == Eigen::Success;
}

double CoarseCorrection::largest_move_mm(int s) const {
  const Sub& sub = subs_[s];
  double largest = 0.0;
  for (Eigen::Index i = 0; i < sub.correction.size(); i += 3) {
    largest = std::max(largest, sub.correction.segment<3>(i).norm());
  }
  return largest;
}

void CoarseCorrection::apply(int s, DeformationEngine& engine) {
  Sub& sub = subs_[s];
  const int n = static_cast<int>(sub.fixed.size());
  for (int l = 0; l < n; ++l) {
    const Weights& w = sub.weights[l];
    Eigen::Vector3d move = Eigen::Vector3d::Zero();
    // The coarse step left held nodes out, the ones the probe lets slide too: they stay put.
    if (!sub.held[l]) {
      for (int a = 0; a < 8; ++a) move += w.weight[a] * sub.correction.segment<3>(3 * w.coarse[a]);
    }
    sub.move.segment<3>(3 * l) = move;
  }
  engine.displace_free_nodes_mm(sub.move);
  // The residual's change under the move, exact for the linear FEM (f = −K u).
  sub.residual.noalias() -= coarse_stiffness(sub) * sub.correction;
}

}  // namespace ultrasim::sim
