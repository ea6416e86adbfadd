#include "ultrasim/sim/fine_correction.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "jacobi_cg.hpp"

namespace ultrasim::sim {

FineCorrection::FineCorrection(std::span<const std::vector<int>> grid_nodes,
                               std::span<const DeformationEngine* const> engines,
                               std::span<const std::uint8_t> fixed_grid_nodes)
    : fixed_(fixed_grid_nodes.begin(), fixed_grid_nodes.end()),
      sliding_(static_cast<int>(fixed_grid_nodes.size())) {
  if (grid_nodes.size() != engines.size()) {
    throw std::invalid_argument("FineCorrection: " + std::to_string(grid_nodes.size()) +
                                " node maps for " + std::to_string(engines.size()) + " engines");
  }
  const int n = static_cast<int>(fixed_.size());
  Eigen::VectorXd diagonal = Eigen::VectorXd::Zero(3 * n);
  std::vector<int> copy_count(n, 0);
  subs_.resize(engines.size());
  for (std::size_t s = 0; s < engines.size(); ++s) {
    Sub& sub = subs_[s];
    sub.grid_node = grid_nodes[s];
    const Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness =
        engines[s]->rest_stiffness_mn_per_mm();
    const int local = static_cast<int>(sub.grid_node.size());
    if (stiffness.rows() != 3 * local || stiffness.cols() != 3 * local) {
      throw std::invalid_argument("FineCorrection: an engine's stiffness does not fit its nodes");
    }
    // Asked once (the answer holds for the engine's life): an engine with its own tangent needs
    // only the rest stiffness's diagonal here (the large case's 25 corotational sub-volumes'
    // block matrices, built and never multiplied, held 55 MB of the kiosk's 647 MB).
    sub.local_in = Eigen::VectorXd::Zero(3 * local);
    sub.local_out = Eigen::VectorXd::Zero(3 * local);
    sub.own_tangent = engines[s]->tangent_stiffness_times(sub.local_in, sub.local_out);
    if (!sub.own_tangent) sub.stiffness = detail::NodeBlockMatrix(stiffness, 1);
    for (int l = 0; l < local; ++l) {
      const int g = sub.grid_node[l];
      if (g < 0 || g >= n) throw std::invalid_argument("FineCorrection: a node off the grid");
      ++copy_count[g];
      for (int d = 0; d < 3; ++d) diagonal[3 * g + d] += stiffness.coeff(3 * l + d, 3 * l + d);
    }
  }
  copies_begin_.assign(n + 1, 0);
  for (int g = 0; g < n; ++g) copies_begin_[g + 1] = copies_begin_[g] + copy_count[g];
  copies_.resize(copies_begin_[n]);
  std::vector<int> next(copies_begin_.begin(), copies_begin_.end() - 1);
  for (std::size_t s = 0; s < subs_.size(); ++s) {
    for (std::size_t l = 0; l < subs_[s].grid_node.size(); ++l) {
      copies_[next[subs_[s].grid_node[l]]++] = {static_cast<int>(s), static_cast<int>(l)};
    }
  }
  inverse_diagonal_ = Eigen::VectorXd::Zero(3 * n);
  for (int i = 0; i < 3 * n; ++i) {
    if (diagonal[i] > 0.0) inverse_diagonal_[i] = 1.0 / diagonal[i];
  }
  free_.assign(n, kHeld);
  stepped_.assign(subs_.size(), 0);
  stepped_list_.reserve(subs_.size());
  for (Eigen::VectorXd* v : {&x_, &r_, &z_, &p_, &q_}) *v = Eigen::VectorXd::Zero(3 * n);
}

void FineCorrection::gather(Eigen::VectorXd& out, bool free_only) const {
  const int n = static_cast<int>(free_.size());
  for (int g = 0; g < n; ++g) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    if (free_[g] || !free_only) {
      for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
        // A sub-volume that did not step holds no forces of this frame.
        if (!stepped_[copies_[c].sub]) continue;
        sum += subs_[copies_[c].sub].local_out.segment<3>(3 * copies_[c].local);
      }
    }
    out.segment<3>(3 * g) = sum;
  }
}

void FineCorrection::multiply(std::span<DeformationEngine* const> engines, const Eigen::VectorXd& p,
                              Eigen::VectorXd& q, hal::JobSystem* jobs) {
  // p is 0 off the free nodes, so each copy takes its grid node's value as it is.
  const auto product = [&](int i) {
    Sub& sub = subs_[stepped_list_[i]];
    for (std::size_t l = 0; l < sub.grid_node.size(); ++l) {
      sub.local_in.segment<3>(3 * l) = p.segment<3>(3 * sub.grid_node[l]);
    }
    if (sub.own_tangent) {
      engines[stepped_list_[i]]->tangent_stiffness_times(sub.local_in, sub.local_out);
    } else {
      sub.stiffness.times_band(0, sub.local_in, nullptr, sub.local_out, sub.spill);
    }
  };
  hal::parallel_for(jobs, static_cast<int>(stepped_list_.size()), product);
  gather(q, true);
}

FineCorrection::Result FineCorrection::correct(std::span<DeformationEngine* const> engines,
                                               std::span<const std::uint8_t> stepped,
                                               int iterations, double relative_tolerance,
                                               const std::function<bool()>& may_continue,
                                               hal::JobSystem* jobs) {
  Result result;
  if (engines.size() != subs_.size() || stepped.size() != subs_.size()) {
    throw std::invalid_argument("FineCorrection::correct: " + std::to_string(engines.size()) +
                                " engines and " + std::to_string(stepped.size()) + " flags for " +
                                std::to_string(subs_.size()) + " sub-volumes");
  }
  stepped_list_.clear();
  for (std::size_t s = 0; s < subs_.size(); ++s) {
    stepped_[s] = stepped[s] ? 1 : 0;
    if (stepped[s]) stepped_list_.push_back(static_cast<int>(s));
  }
  if (stepped_list_.empty() || iterations <= 0) return result;
  const int n = static_cast<int>(free_.size());
  bool any_free = false;
  sliding_.clear();
  for (int g = 0; g < n; ++g) {
    // Held if any copy is (or did not step); sliding if any copy slides, along its normal, the
    // copies' friction summed.
    std::uint8_t state = fixed_[g] ? kHeld : kFree;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero(), friction_mn = Eigen::Vector3d::Zero();
    for (int c = copies_begin_[g]; state != kHeld && c < copies_begin_[g + 1]; ++c) {
      const DeformationEngine& engine = *engines[copies_[c].sub];
      if (!stepped[copies_[c].sub]) {
        state = kHeld;
      } else if (engine.holds_node(copies_[c].local)) {
        const DeformationEngine::SlidingHold* hold = engine.sliding_hold(copies_[c].local);
        // Copies that slide along different planes cannot move alike: held.
        if (hold == nullptr ||
            (state == kSliding && !(hold->normal.dot(normal) > kSameNormalCosine))) {
          state = kHeld;
        } else {
          state = kSliding;
          normal = hold->normal;
          friction_mn += hold->friction_mn;
        }
      }
    }
    free_[g] = state;
    if (state == kSliding) sliding_.add(g, normal, friction_mn);
    any_free = any_free || state != kHeld;
  }
  if (!any_free) return result;
  // The residual: the tissue's forces summed over the copies (the seams' pulls on a node whose
  // every copy moves alike cancel).
  const auto forces = [&](int i) {
    const int s = stepped_list_[i];
    engines[s]->tissue_forces_mn(subs_[s].local_out);
  };
  hal::parallel_for(jobs, static_cast<int>(stepped_list_.size()), forces);
  // The load: the same forces on every node, the probe's and the base's reactions included (a
  // node not stepped counts its stepped copies only: a scale, not a balance).
  gather(r_, false);
  const double load = r_.norm();
  gather(r_, true);
  sliding_.add_friction(r_);
  const auto filter = [this](Eigen::VectorXd& v) { sliding_.project_all(v); };
  filter(r_);
  x_.setZero();
  z_ = inverse_diagonal_.cwiseProduct(r_);
  filter(z_);
  p_ = z_;
  double rz = r_.dot(z_);
  double norm = r_.norm();
  while (result.iterations < iterations && rz > 0.0 && norm > relative_tolerance * load &&
         (!may_continue || may_continue())) {
    multiply(engines, p_, q_, jobs);
    filter(q_);
    // Not positive definite along p: stop with what there is.
    if (!jacobi_cg_update(inverse_diagonal_, q_, x_, r_, z_, p_, rz, filter)) break;
    norm = r_.norm();
    ++result.iterations;
  }
  result.relative_residual = load > 0.0 ? norm / load : 0.0;
  if (result.iterations == 0 || !x_.allFinite()) return result;
  for (int g = 0; g < n; ++g) {
    result.largest_move_mm = std::max(result.largest_move_mm, x_.segment<3>(3 * g).norm());
  }
  const auto move = [&](int i) {
    const int s = stepped_list_[i];
    Sub& sub = subs_[s];
    for (std::size_t l = 0; l < sub.grid_node.size(); ++l) {
      sub.local_in.segment<3>(3 * l) = x_.segment<3>(3 * sub.grid_node[l]);
    }
    engines[s]->displace_free_nodes_mm(sub.local_in);
  };
  hal::parallel_for(jobs, static_cast<int>(stepped_list_.size()), move);
  return result;
}

}  // namespace ultrasim::sim
