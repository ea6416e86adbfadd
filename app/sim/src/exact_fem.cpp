#include "ultrasim/sim/exact_fem.hpp"

#include <stdexcept>
#include <string>

#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::sim {

ExactFem::ExactFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
                   std::span<const std::uint8_t> fixed_nodes, const ExactFemSettings& settings)
    : settings_(settings),
      rest_(mesh.rest_positions_mm),
      fixed_(fixed_nodes.begin(), fixed_nodes.end()),
      node_slot_(mesh.rest_positions_mm.size(), -1),
      deformed_(mesh.rest_positions_mm) {
  // LinearFem validates the inputs (one material per tet, ranges, positive volumes, at least one
  // fixed node) and assembles the identical stiffness: one model, two solvers.
  stiffness_ = LinearFem(mesh, tet_materials, fixed_nodes, FemSettings{}).stiffness();
  if (settings.max_cached_nodes < 0) {
    throw std::invalid_argument("ExactFem: max_cached_nodes must be >= 0");
  }
  const int dofs = 3 * node_count();
  global_to_free_.assign(dofs, -1);
  for (int node = 0; node < node_count(); ++node) {
    if (fixed_[node]) continue;
    for (int i = 0; i < 3; ++i) {
      global_to_free_[3 * node + i] = static_cast<int>(free_to_global_.size());
      free_to_global_.push_back(3 * node + i);
    }
  }
  const int n_free = free_dof_count();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(stiffness_.nonZeros());
  for (int row = 0; row < dofs; ++row) {
    const int fr = global_to_free_[row];
    if (fr < 0) continue;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(stiffness_, row); it;
         ++it) {
      const int fc = global_to_free_[it.col()];
      if (fc >= 0) triplets.emplace_back(fr, fc, it.value());
    }
  }
  Eigen::SparseMatrix<double> k_free(n_free, n_free);
  k_free.setFromTriplets(triplets.begin(), triplets.end());
  factor_.compute(k_free);
  ++factorizations_;
  // LDLᵀ "succeeds" on a singular matrix with a zero pivot; a positive-definite K_ff has all
  // pivots positive, so check them rather than trust info() alone.
  if (factor_.info() != Eigen::Success || (n_free > 0 && !(factor_.vectorD().minCoeff() > 0.0))) {
    throw std::invalid_argument(
        "ExactFem: the stiffness on the free DOFs is singular (not positive definite): a part of "
        "the mesh is not held by any fixed node");
  }

  load_mn_ = Eigen::VectorXd::Zero(dofs);
  load_response_ = Eigen::VectorXd::Zero(n_free);
  u_ = Eigen::VectorXd::Zero(dofs);
  reaction_ = Eigen::VectorXd::Zero(dofs);
  u_free_ = Eigen::VectorXd::Zero(n_free);
  rhs_free_ = Eigen::VectorXd::Zero(n_free);
}

void ExactFem::set_nodal_load(int node, const Eigen::Vector3d& force_mn) {
  if (fixed_[node]) return;
  load_mn_.segment<3>(3 * node) = force_mn;
  loads_dirty_ = true;
}

void ExactFem::clear_nodal_loads() {
  load_mn_.setZero();
  loads_dirty_ = true;
}

Eigen::Vector3d ExactFem::reaction_force_mn(int node) const {
  return reaction_.segment<3>(3 * node);
}

int ExactFem::columns_for(int node, ExactFemStepStats& stats) {
  int slot = node_slot_[node];
  if (slot >= 0) {
    stats.columns_reused += 3;
    last_use_[slot] = frame_;
    return slot;
  }
  if (static_cast<int>(cache_slot_node_.size()) < settings_.max_cached_nodes) {
    slot = static_cast<int>(cache_slot_node_.size());
    cache_slot_node_.push_back(-1);
    cache_columns_.emplace_back();
    last_use_.push_back(0);
  } else {
    // Evict the least recently used node not held this frame (solve() stamped those with frame_).
    int oldest = frame_;
    for (int s = 0; s < static_cast<int>(cache_slot_node_.size()); ++s) {
      if (last_use_[s] < oldest) {
        oldest = last_use_[s];
        slot = s;
      }
    }
    if (slot < 0) {
      slot = static_cast<int>(cache_slot_node_.size());
      cache_slot_node_.push_back(-1);
      cache_columns_.emplace_back();
      last_use_.push_back(0);
    } else {
      node_slot_[cache_slot_node_[slot]] = -1;
    }
  }
  const int n_free = free_dof_count();
  Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(n_free, 3);
  for (int i = 0; i < 3; ++i) unit(global_to_free_[3 * node + i], i) = 1.0;
  cache_columns_[slot] = factor_.solve(unit);
  cache_slot_node_[slot] = node;
  node_slot_[node] = slot;
  last_use_[slot] = frame_;
  stats.columns_computed += 3;
  total_columns_computed_ += 3;
  return slot;
}

ExactFemStepStats ExactFem::solve(std::span<const PrescribedNode> held) {
  ExactFemStepStats stats;
  ++frame_;
  held_nodes_.clear();
  for (const auto& h : held) {
    if (h.node < 0 || h.node >= node_count()) {
      throw std::out_of_range("ExactFem::solve: node " + std::to_string(h.node) + " out of range");
    }
    if (fixed_[h.node]) continue;
    held_nodes_.push_back(h.node);
    // Nodes already cached and held again this frame must not be evicted by new ones.
    if (node_slot_[h.node] >= 0) last_use_[node_slot_[h.node]] = frame_;
  }
  if (loads_dirty_) {
    for (int f = 0; f < free_dof_count(); ++f) rhs_free_[f] = load_mn_[free_to_global_[f]];
    load_response_ = factor_.solve(rhs_free_);
    loads_dirty_ = false;
    stats.load_solves = 1;
  }
  const int k = static_cast<int>(held_nodes_.size());
  held_slots_.resize(k);
  for (int a = 0; a < k; ++a) held_slots_[a] = columns_for(held_nodes_[a], stats);

  // Capacitance system (Eᵀ K⁻¹ E) λ = d − Eᵀ K⁻¹ f: a principal submatrix of K_ff⁻¹, so SPD.
  const int m = 3 * k;
  capacitance_.resize(m, m);
  rhs_.resize(m);
  {
    int a = 0;
    for (const auto& h : held) {
      if (fixed_[h.node]) continue;
      for (int i = 0; i < 3; ++i) {
        const int fr = global_to_free_[3 * h.node + i];
        rhs_[3 * a + i] = h.displacement_mm[i] - load_response_[fr];
        for (int b = 0; b < k; ++b) {
          capacitance_.block<1, 3>(3 * a + i, 3 * b) = cache_columns_[held_slots_[b]].row(fr);
        }
      }
      ++a;
    }
  }
  u_free_ = load_response_;
  lambda_mn_.resize(m);
  if (m > 0) {
    capacitance_llt_.compute(capacitance_);
    if (capacitance_llt_.info() != Eigen::Success) {
      throw std::invalid_argument(
          "ExactFem::solve: capacitance matrix not positive definite (a node listed twice?)");
    }
    lambda_mn_ = capacitance_llt_.solve(rhs_);
    for (int b = 0; b < k; ++b) {
      u_free_.noalias() += cache_columns_[held_slots_[b]] * lambda_mn_.segment<3>(3 * b);
    }
  }

  u_.setZero();
  for (int f = 0; f < free_dof_count(); ++f) u_[free_to_global_[f]] = u_free_[f];
  // Held DOFs equal their targets to rounding; write the targets so they are exact.
  for (const auto& h : held) {
    if (!fixed_[h.node]) u_.segment<3>(3 * h.node) = h.displacement_mm;
  }
  // Reactions: K u − f, nonzero only on held and fixed DOFs (the free rows balance).
  reaction_.noalias() = stiffness_ * u_;
  reaction_ -= load_mn_;
  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (int b = 0; b < k; ++b) total_mn += lambda_mn_.segment<3>(3 * b);
  stats.contact_nodes = k;
  stats.condensed_size = m;
  stats.contact_force_n = total_mn.norm() / 1000.0;
  update_deformed();
  return stats;
}

ExactFemStepStats ExactFem::step(const SphereCollider& collider) {
  contact_scratch_.clear();
  // A node left exactly on the surface by the last frame counts as inside, so a probe that holds
  // still keeps its contact set instead of letting it go and taking it back on alternate frames.
  const double reach_mm = collider.radius_mm * (1.0 + 1e-9);
  for (int node = 0; node < node_count(); ++node) {
    if (fixed_[node]) continue;
    const Eigen::Vector3d d = deformed_[node] - collider.center_mm;
    const double dist = d.norm();
    if (!(dist < reach_mm)) continue;
    const Eigen::Vector3d dir = dist > 1e-12 ? Eigen::Vector3d(d / dist) : Eigen::Vector3d(0, 0, 1);
    contact_scratch_.push_back(
        {node, Eigen::Vector3d(collider.center_mm + collider.radius_mm * dir - rest_[node])});
  }
  return solve(contact_scratch_);
}

void ExactFem::update_deformed() {
  for (int node = 0; node < node_count(); ++node) {
    deformed_[node] = rest_[node] + u_.segment<3>(3 * node);
  }
}

}  // namespace ultrasim::sim
