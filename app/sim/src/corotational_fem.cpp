#include "ultrasim/sim/corotational_fem.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "model_checks.hpp"
#include "polar_rotation.hpp"
#include "rotation_turns.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::sim {

using corotational_detail::polar_rotation;

namespace {

// Work is split into chunks of fixed size, not one per thread, so that sums come out in the same
// order on any thread count (and chunks are big enough to amortise a task's dispatch).
constexpr int kTetsPerChunk = 256;
constexpr int kNodesPerChunk = 64;
// A node left exactly on the probe's surface last frame is still in contact (find_contacts).
constexpr double kContactToleranceMm = 1e-6;
// An inverting frame is retried at 1/2, 1/4, ... of its update, this many times.
constexpr int kMaxBacktracks = 10;
// The linear solves of solve_to_convergence() are run to this relative residual.
constexpr double kConvergedRelativeResidual = 1e-12;

int encode_contribution(int tet, int a, int b) {
  return 16 * tet + 4 * a + b;
}

[[gnu::always_inline]] inline Eigen::Matrix3d edge_matrix(const Eigen::Vector3d& x0,
                                                          const Eigen::Vector3d& x1,
                                                          const Eigen::Vector3d& x2,
                                                          const Eigen::Vector3d& x3) {
  // Column by column: the comma initialiser goes through dynamic-size blocks, a call per column
  // (as long as the determinant itself in the inversion count, which builds one a tet a step).
  Eigen::Matrix3d e;
  e.col(0) = x1 - x0;
  e.col(1) = x2 - x0;
  e.col(2) = x3 - x0;
  return e;
}

// Of a tet's node pair (a, b), which is the row and which the column of their block above K_R's
// diagonal: the lower node's row (K_ba = K_abᵀ).
std::pair<int, int> upper_block_pair(const geometry::Tet& tet, int a, int b) {
  return tet[a] <= tet[b] ? std::pair{a, b} : std::pair{b, a};
}

// x_b − x_0 of tet `tet` for a node-major displacement vector on top of rest positions.
[[gnu::always_inline]] inline Eigen::Matrix3d deformed_edges(
    const geometry::Tet& tet, const std::vector<Eigen::Vector3d>& rest, const Eigen::VectorXd& u) {
  const auto x = [&](int a) -> Eigen::Vector3d { return rest[tet[a]] + u.segment<3>(3 * tet[a]); };
  return edge_matrix(x(0), x(1), x(2), x(3));
}

// Isotropic linear elastic stress of a small strain (kPa) times the tet's volume (mm³): applied
// to a shape-function gradient (1/mm) it gives a nodal force in mN.
Eigen::Matrix3d volume_stress(const Eigen::Matrix3d& strain, const Eigen::Vector2d& lame_volume) {
  return lame_volume[0] * strain.trace() * Eigen::Matrix3d::Identity() +
         2.0 * lame_volume[1] * strain;
}

// Node block K_ab of a linear tet's stiffness from its shape-function gradients: for isotropic
// linear elasticity K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I). With the rotated
// gradients R g it is the warped block R K_ab Rᵀ directly: ~20 flops instead of two 3×3 products.
[[gnu::always_inline]] inline Eigen::Matrix3d stiffness_block(const Eigen::Vector3d& ga,
                                                              const Eigen::Vector3d& gb,
                                                              const Eigen::Vector2d& lame_volume) {
  const Eigen::Vector3d lambda_ga = lame_volume[0] * ga, mu_gb = lame_volume[1] * gb;
  Eigen::Matrix3d k;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) k(i, j) = lambda_ga[i] * gb[j] + mu_gb[i] * ga[j];
  }
  k.diagonal().array() += mu_gb.dot(ga);
  return k;
}

}  // namespace

CorotationalFem::CorotationalFem(const geometry::TetMesh& mesh,
                                 std::span<const Material> tet_materials,
                                 std::span<const std::uint8_t> fixed_nodes,
                                 const CorotationalSettings& settings, hal::JobSystem* jobs)
    : settings_(settings),
      jobs_(jobs),
      rest_(mesh.rest_positions_mm),
      tets_(mesh.tets),
      fixed_(fixed_nodes.begin(), fixed_nodes.end()),
      sliding_(mesh.node_count()) {
  const int n = mesh.node_count();
  fixed_count_ = check_tet_model("CorotationalFem", mesh, tet_materials, fixed_nodes);
  if (settings.pcg_iterations_per_frame < 1) {
    throw std::invalid_argument("pcg_iterations_per_frame must be >= 1");
  }
  if (!(settings.relative_tolerance >= 0.0) || !std::isfinite(settings.relative_tolerance)) {
    throw std::invalid_argument("relative_tolerance must be finite and >= 0");
  }
  if (!(settings.max_inverted_fraction >= 0.0 && settings.max_inverted_fraction <= 1.0)) {
    throw std::invalid_argument("max_inverted_fraction must be in [0, 1]");
  }
  if (!(settings.rotation_update_tolerance >= 0.0 && settings.rotation_update_tolerance <= 1.0)) {
    throw std::invalid_argument("rotation_update_tolerance must be in [0, 1]");
  }
  if (!(settings.max_rotation_updates_fraction > 0.0 &&
        settings.max_rotation_updates_fraction <= 1.0)) {
    throw std::invalid_argument("max_rotation_updates_fraction must be in (0, 1]");
  }
  if (settings.turn_check_interval_frames < 1) {
    throw std::invalid_argument("turn_check_interval_frames must be 1 or more");
  }
  if (settings.rotation_update_interval_frames < 1 || settings.rotation_update_phase < 0 ||
      settings.rotation_update_phase >= settings.rotation_update_interval_frames) {
    throw std::invalid_argument(
        "rotation_update_interval_frames must be 1 or more, rotation_update_phase in [0, it)");
  }
  if (settings.max_update_turns_held < 0) {
    throw std::invalid_argument("max_update_turns_held must be 0 or more");
  }
  if (settings.tissue_product_refresh_steps < 1) {
    throw std::invalid_argument("tissue_product_refresh_steps must be 1 or more");
  }
  if (!(settings.term_swap_max_fraction >= 0.0 && settings.term_swap_max_fraction <= 1.0)) {
    throw std::invalid_argument("term_swap_max_fraction must be in [0, 1]");
  }
  check_held_contact_settings(settings.contact, "CorotationalFem");
  precompute_tets(tet_materials);
  build_pattern_and_scatter_map();

  const int dofs = 3 * n;
  u_ = rhs_ = inverse_diagonal_ = load_mn_ = Eigen::VectorXd::Zero(dofs);
  anchor_stiffness_ = anchor_load_mn_ = Eigen::VectorXd::Zero(dofs);
  r_ = z_ = p_ = q_ = u_before_step_ = Eigen::VectorXd::Zero(dofs);
  tissue_product_ = tissue_product_u_ = Eigen::VectorXd::Zero(dofs);
  moved_nodes_.reserve(n);
  held_.assign(n, 0);
  contact_push_mn_.assign(n, 0.0);
  contacts_.reserve(n);  // every node at most once: step() never grows it
  anchored_nodes_.reserve(n);
  next_anchored_nodes_.reserve(n);
  prescribed_.assign(n, 0);
  prescribed_u_.assign(n, Eigen::Vector3d::Zero());
  deformed_ = rest_;
  chunk_sums_.assign(std::max(tet_chunks(), node_chunks()), Eigen::Vector4d::Zero());
  chunk_slides_.assign(node_chunks(), 0);
  meets_constraint_.assign(n, 0);

  // At rest every rotation is the identity: K_R is LinearFem's stiffness and the rhs is zero.
  rotation_.assign(tets_.size(), Eigen::Matrix3d::Identity());
  rotated_gradients_ = shape_gradients_;
  element_rhs_.assign(tets_.size(), Eigen::Matrix<double, 3, 4>::Zero());
  rotation_moved_.assign(tets_.size(), 1);
  turn_.assign(tets_.size(), 0.0);
  turn_scratch_.reserve(tets_.size());
  moved_tets_.reserve(tets_.size());
  node_moved_.assign(n, 1);
  sum_moved_rows_again_ = true;
  loads_changed_ = true;
  assemble_warped_system();
}

void CorotationalFem::precompute_tets(std::span<const Material> tet_materials) {
  shape_gradients_.resize(tets_.size());
  lame_volume_.resize(tets_.size());
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    const auto& tet = tets_[t];
    const Material& m = tet_materials[t];
    const auto& p = rest_;
    const Eigen::Matrix3d edges = edge_matrix(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]);
    const double volume = edges.determinant() / 6.0;
    // Rows of edges⁻¹ are the gradients of the shape functions of nodes 1..3.
    const Eigen::Matrix3d grads = edges.inverse();
    auto& g = shape_gradients_[t];
    g.rightCols<3>() = grads.transpose();
    g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
    const double e = m.youngs_modulus_kpa, nu = m.poisson_ratio;
    lame_volume_[t] =
        volume * Eigen::Vector2d(e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu)));
    check_against_linear_fem(t, m);
  }
}

void CorotationalFem::check_against_linear_fem(int t, const Material& m) const {
  // LinearFem's element stiffness is the model; the gradient form above only evaluates it faster.
  // Compare them once per tet so the two engines cannot drift apart.
  const auto& tet = tets_[t];
  const auto& p = rest_;
  const Eigen::Matrix<double, 12, 12> ke = tet_stiffness(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]],
                                                         m.youngs_modulus_kpa, m.poisson_ratio);
  double mismatch = 0.0;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      const Eigen::Matrix3d k =
          stiffness_block(shape_gradients_[t].col(a), shape_gradients_[t].col(b), lame_volume_[t]);
      mismatch = std::max(mismatch, (k - ke.block<3, 3>(3 * a, 3 * b)).cwiseAbs().maxCoeff());
    }
  }
  if (!(mismatch <= 1e-9 * ke.cwiseAbs().maxCoeff())) {
    throw std::logic_error("CorotationalFem: element stiffness of tet " + std::to_string(t) +
                           " differs from tet_stiffness(); the two material models drifted apart");
  }
}

void CorotationalFem::build_pattern_and_scatter_map() {
  const int n = node_count();
  // Node adjacency (nodes sharing a tet, and each node itself): the block pattern of K_R.
  std::vector<std::vector<int>> neighbours(n);
  for (const auto& tet : tets_) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) neighbours[tet[a]].push_back(tet[b]);
    }
  }
  block_row_start_.assign(n + 1, 0);
  block_col_.clear();
  diagonal_block_.assign(n, -1);
  for (int node = 0; node < n; ++node) {
    auto& cols = neighbours[node];
    cols.push_back(node);  // a node in no tet still gets a diagonal block
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
    for (int c : cols) {
      if (c == node) diagonal_block_[node] = static_cast<int>(block_col_.size());
      block_col_.push_back(c);
    }
    block_row_start_[node + 1] = static_cast<int>(block_col_.size());
  }
  block_value_.assign(block_col_.size(), Eigen::Matrix3d::Zero());

  const auto block_index = [&](int row, int col) {
    const auto first = block_col_.begin() + block_row_start_[row];
    const auto last = block_col_.begin() + block_row_start_[row + 1];
    return static_cast<int>(std::lower_bound(first, last, col) - block_col_.begin());
  };
  // K_R is symmetric: only blocks on or above the diagonal are summed from the tets, each block
  // below it is the transpose of its mirror.
  mirror_block_.assign(block_col_.size(), -1);
  for (int node = 0; node < n; ++node) {
    for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
      if (block_col_[k] < node) mirror_block_[k] = block_index(block_col_[k], node);
    }
  }
  // Counting sort of the element blocks by the global block they add to, in tet order, so each
  // global block sums its contributions in a fixed order.
  std::vector<int> target(tets_.size() * 16, -1);
  contribution_start_.assign(block_col_.size() + 1, 0);
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        if (tets_[t][a] > tets_[t][b]) continue;  // below the diagonal: mirrored
        const int k = block_index(tets_[t][a], tets_[t][b]);
        target[16 * t + 4 * a + b] = k;
        ++contribution_start_[k + 1];
      }
    }
  }
  for (std::size_t k = 0; k < block_col_.size(); ++k) {
    contribution_start_[k + 1] += contribution_start_[k];
  }
  // Each tet's ten blocks above the diagonal as offsets into their rows: a moved tet's terms are
  // swapped without a search for its blocks (the soak's touched sub-volumes: the search's
  // dependent loads took most of the swaps' time).
  tet_blocks_.resize(tets_.size());
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    int pair = 0;
    for (int a = 0; a < 4; ++a) {
      for (int b = a; b < 4; ++b) {
        const auto [row, col] = upper_block_pair(tets_[t], a, b);
        const int offset = target[16 * t + 4 * row + col] - block_row_start_[tets_[t][row]];
        if (offset > std::numeric_limits<std::uint16_t>::max()) {
          throw std::invalid_argument("CorotationalFem: node " + std::to_string(tets_[t][row]) +
                                      " has more neighbours than a block offset holds");
        }
        tet_blocks_[t][pair++] = static_cast<std::uint16_t>(offset);
      }
    }
  }
  std::vector<int> next(contribution_start_.begin(), contribution_start_.end() - 1);
  contribution_.resize(contribution_start_.back());
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int ab = 0; ab < 16; ++ab) {
      const int k = target[16 * t + ab];
      if (k >= 0)
        contribution_[next[k]++] = encode_contribution(static_cast<int>(t), ab / 4, ab % 4);
    }
  }
}

int CorotationalFem::tet_chunks() const {
  return (tet_count() + kTetsPerChunk - 1) / kTetsPerChunk;
}

int CorotationalFem::node_chunks() const {
  return (node_count() + kNodesPerChunk - 1) / kNodesPerChunk;
}

std::pair<int, int> CorotationalFem::tet_range(int chunk) const {
  return {chunk * kTetsPerChunk, std::min(tet_count(), (chunk + 1) * kTetsPerChunk)};
}

std::pair<int, int> CorotationalFem::node_range(int chunk) const {
  return {chunk * kNodesPerChunk, std::min(node_count(), (chunk + 1) * kNodesPerChunk)};
}

template <typename Body>
void CorotationalFem::for_each_chunk(int chunks, Body&& body) const {
  hal::parallel_for(jobs_, chunks, [&body](int chunk) { body(chunk); });
}

Eigen::Vector4d CorotationalFem::sum_chunks(int chunks) const {
  Eigen::Vector4d total = Eigen::Vector4d::Zero();
  for (int c = 0; c < chunks; ++c) total += chunk_sums_[c];
  return total;
}

void CorotationalFem::prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm) {
  if (node < 0 || node >= node_count()) {
    throw std::out_of_range("CorotationalFem: node " + std::to_string(node) + " out of range");
  }
  if (!displacement_mm.allFinite()) {
    throw std::invalid_argument("CorotationalFem: prescribed displacement must be finite");
  }
  if (fixed_[node]) return;
  prescribed_[node] = 1;
  prescribed_u_[node] = displacement_mm;
}

void CorotationalFem::release_displacement(int node) {
  if (node < 0 || node >= node_count()) {
    throw std::out_of_range("CorotationalFem: node " + std::to_string(node) + " out of range");
  }
  prescribed_[node] = 0;
}

void CorotationalFem::set_nodal_load(int node, const Eigen::Vector3d& force_mn) {
  if (node < 0 || node >= node_count()) {
    throw std::out_of_range("CorotationalFem: node " + std::to_string(node) + " out of range");
  }
  if (!force_mn.allFinite()) {
    throw std::invalid_argument("CorotationalFem: nodal load must be finite");
  }
  if (fixed_[node]) return;
  load_mn_.segment<3>(3 * node) = force_mn;
  loads_changed_ = true;
}

void CorotationalFem::clear_nodal_loads() {
  load_mn_.setZero();
  loads_changed_ = true;
}

void CorotationalFem::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != 3 * static_cast<Eigen::Index>(node_count())) {
    throw std::invalid_argument("CorotationalFem::set_displacements_mm: need 3 × " +
                                std::to_string(node_count()) + " entries, got " +
                                std::to_string(u_mm.size()));
  }
  if (!u_mm.allFinite()) {
    throw std::invalid_argument("CorotationalFem::set_displacements_mm: non-finite displacement");
  }
  u_ = u_mm;
  for (int node = 0; node < node_count(); ++node) {
    if (fixed_[node]) u_.segment<3>(3 * node).setZero();
  }
  // The contacts belonged to the old shape: the next step finds them on this one. The rotations
  // stay: the next step extracts those of the tets that have turned from them by the tolerance,
  // as for any frame. (A stitched volume reverts a refused frame with this: its rotations came
  // from that frame's start, the shape it goes back to. Extracting every one there made each
  // frame of a run of refusals pay a full extraction and assembly: the large soak's corotational
  // frames p99 46 ms.) Every tet's turn is checked on this shape, not once in
  // turn_check_interval_frames.
  check_every_tet_ = true;
  contacts_.clear();
  stop_sliding();
  for (int node = 0; node < node_count(); ++node) held_[node] = fixed_[node] || prescribed_[node];
  std::fill(contact_push_mn_.begin(), contact_push_mn_.end(), 0.0);
  update_deformed();
}

void CorotationalFem::apply_constraints(const ProbeCollider* probe) {
  stop_sliding();
  if (probe == nullptr) {
    contacts_.clear();
    hold_constrained_nodes();
    return;
  }
  find_contacts(*probe, deformed_, fixed_, kContactToleranceMm, contacts_);
  // A prescribed node stays where the test put it. A node the probe had to pull last frame (the
  // tissue was drawing it away from the probe) is let go where it is: the probe can only push.
  // Without this a node once caught on the face stays stuck to it as the probe moves on, and the
  // layers under the face are pulled flat against it.
  std::erase_if(contacts_, [&](const NodeContact& c) {
    return prescribed_[c.node] != 0 || contact_push_mn_[c.node] < 0.0;
  });
  const int first_follower = static_cast<int>(contacts_.size());
  add_followers(*probe);
  hold_constrained_nodes();
  let_go_of_followers_that_would_pull(first_follower);
  if (settings_.contact.model == HeldContactModel::kCoulombSlip) choose_sliding_nodes();
}

void CorotationalFem::stop_sliding() {
  sliding_.clear();
  std::fill(chunk_slides_.begin(), chunk_slides_.end(), 0);
}

void CorotationalFem::choose_sliding_nodes() {
  // As the PCG FEM's (coulomb_hold), with last frame's warped stiffness: a node that slides is
  // held along the probe's normal only, in the CG below.
  for (const NodeContact& c : contacts_) {
    const HeldNodeLaw law =
        coulomb_hold(c.normal, -node_force_mn(c.node), settings_.contact.friction_coefficient);
    if (!law.slides) continue;
    sliding_.add(c.node, c.normal, law.friction_mn);
    chunk_slides_[c.node / kNodesPerChunk] = 1;
    held_[c.node] = 0;
  }
}

void CorotationalFem::add_followers(const ProbeCollider& probe) {
  // A node the probe pushed on last frame and has now moved away from (the probe lifting) stays
  // on its surface: compressed tissue follows a lifting probe. Dropping every such node as soon
  // as the probe rises a micrometre would let the whole contact patch spring back into the
  // probe on the next frame. held_ marks this frame's contacts here; hold_constrained_nodes()
  // rebuilds it.
  std::fill(held_.begin(), held_.end(), 0);
  for (const auto& c : contacts_) held_[c.node] = 1;
  for (int node = 0; node < node_count(); ++node) {
    if (held_[node] || !(contact_push_mn_[node] > 0.0) || fixed_[node] || prescribed_[node]) {
      continue;
    }
    const SurfacePoint s = probe.closest_surface_point(deformed_[node]);
    contacts_.push_back({node, s.point_mm, s.normal, 0.0});  // capacity reserved: no allocation
  }
}

void CorotationalFem::let_go_of_followers_that_would_pull(int first_follower) {
  // Holding a follower on the moved surface may now take a pull (the tissue has relaxed below
  // it). Judge with last frame's warped stiffness, the neighbours already moved: K_R u − b along
  // the normal. Let go of those where it is not a push; they stay where they were.
  int kept = first_follower;
  for (int i = first_follower; i < static_cast<int>(contacts_.size()); ++i) {
    const NodeContact& c = contacts_[i];
    if (node_force_mn(c.node).dot(c.normal) > 0.0) {
      contacts_[kept++] = c;
      continue;
    }
    held_[c.node] = 0;
    u_.segment<3>(3 * c.node) = u_before_step_.segment<3>(3 * c.node);
  }
  contacts_.resize(kept);  // shrinking: no allocation
}

Eigen::Vector3d CorotationalFem::warped_row_times(int node, const Eigen::VectorXd& v) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
    sum.noalias() += block_value_[k].lazyProduct(v.segment<3>(3 * block_col_[k]));
  }
  return sum;
}

Eigen::Vector3d CorotationalFem::add_element_forces(int node, Eigen::Vector3d sum) const {
  // The diagonal block's contributions are exactly the tets holding the node, one each.
  const int diag = diagonal_block_[node];
  for (int c = contribution_start_[diag]; c < contribution_start_[diag + 1]; ++c) {
    const int code = contribution_[c];
    sum += element_rhs_[code >> 4].col((code >> 2) & 3);
  }
  return sum;
}

Eigen::Matrix3d CorotationalFem::summed_block(
    int k, const std::vector<Eigen::Matrix<double, 3, 4>>& gradients) const {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (int c = contribution_start_[k]; c < contribution_start_[k + 1]; ++c) {
    const int code = contribution_[c];
    const int t = code >> 4, a = (code >> 2) & 3, b = code & 3;
    sum += stiffness_block(gradients[t].col(a), gradients[t].col(b), lame_volume_[t]);
  }
  return sum;
}

Eigen::Vector3d CorotationalFem::node_force_mn(int node) const {
  return warped_row_times(node, u_) +
         anchor_stiffness_.segment<3>(3 * node).cwiseProduct(u_.segment<3>(3 * node)) -
         anchor_load_mn_.segment<3>(3 * node) - rhs_.segment<3>(3 * node);
}

void CorotationalFem::update_inverse_diagonal(int node) {
  // A node in no tet (and no anchor) has a zero diagonal and is left alone.
  const Eigen::Vector3d d =
      block_value_[diagonal_block_[node]].diagonal() + anchor_stiffness_.segment<3>(3 * node);
  inverse_diagonal_.segment<3>(3 * node) =
      (d.array() > 0.0).select(d.cwiseInverse(), Eigen::Vector3d::Zero());
}

void CorotationalFem::set_anchor_springs(std::span<const AnchorSpring> anchors) {
  check_anchor_springs(anchors, node_count());
  // A stitched sub-volume anchors the same nodes as stiffly every step, only their targets move:
  // such a node keeps its inverse diagonal, which reads its diagonal block (a cache miss a node;
  // releasing and setting every anchor again took half of a large-case sub-volume's anchors,
  // 65 of 130 µs). Both lists are in increasing node order.
  const auto release = [this](int node) {
    anchor_stiffness_.segment<3>(3 * node).setZero();
    anchor_load_mn_.segment<3>(3 * node).setZero();
    update_inverse_diagonal(node);
  };
  std::size_t old = 0;
  next_anchored_nodes_.clear();
  for (const auto& a : anchors) {
    while (old < anchored_nodes_.size() && anchored_nodes_[old] < a.node) {
      release(anchored_nodes_[old++]);
    }
    const bool was_anchored = old < anchored_nodes_.size() && anchored_nodes_[old] == a.node;
    if (was_anchored) ++old;
    // k (target − x) = k (target − rest) − k u: a load and a diagonal stiffness.
    anchor_load_mn_.segment<3>(3 * a.node) = a.stiffness_mn_per_mm * (a.target_mm - rest_[a.node]);
    if (!was_anchored || anchor_stiffness_[3 * a.node] != a.stiffness_mn_per_mm) {
      anchor_stiffness_.segment<3>(3 * a.node).setConstant(a.stiffness_mn_per_mm);
      update_inverse_diagonal(a.node);
    }
    next_anchored_nodes_.push_back(a.node);  // at most one per node: no allocation once warm
  }
  while (old < anchored_nodes_.size()) release(anchored_nodes_[old++]);
  anchored_nodes_.swap(next_anchored_nodes_);
}

bool CorotationalFem::tangent_stiffness_times(const Eigen::VectorXd& v_mm,
                                              Eigen::VectorXd& out_mn) const {
  for (int n = 0; n < node_count(); ++n) out_mn.segment<3>(3 * n) = warped_row_times(n, v_mm);
  return true;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> CorotationalFem::rest_stiffness_mn_per_mm() const {
  // The warped stiffness's blocks with every rotation the identity.
  std::vector<Eigen::Matrix3d> blocks(block_col_.size());
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    if (mirror_block_[k] < 0) blocks[k] = summed_block(static_cast<int>(k), shape_gradients_);
  }
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    if (mirror_block_[k] >= 0) blocks[k] = blocks[mirror_block_[k]].transpose();
  }
  return node_blocks_as_matrix(blocks);
}

void CorotationalFem::tissue_forces_mn(Eigen::VectorXd& forces_mn) const {
  // Σ R K_e (x0 − Rᵀ x0) − K_R u: the tets' pull at the current shape with the rotations they
  // hold (the element terms summed here, not taken from rhs_, which holds the loads of the last
  // assembly).
  for (int node = 0; node < node_count(); ++node) {
    forces_mn.segment<3>(3 * node) =
        add_element_forces(node, Eigen::Vector3d::Zero()) - warped_row_times(node, u_);
  }
}

void CorotationalFem::displace_free_nodes_mm(const Eigen::VectorXd& du_mm) {
  displace_free_and_sliding_nodes(*this, sliding_, prescribed_, du_mm, u_);
  update_deformed();
}

void CorotationalFem::move_held_node_mm(int node, const Eigen::Vector3d& position_mm) {
  if (fixed_[node] || !holds_node(node)) return;
  u_.segment<3>(3 * node) = position_mm - rest_[node];
  deformed_[node] = position_mm;
}

void CorotationalFem::hold_constrained_nodes() {
  for (int node = 0; node < node_count(); ++node) {
    held_[node] = fixed_[node] || prescribed_[node];
    if (fixed_[node]) u_.segment<3>(3 * node).setZero();
    if (prescribed_[node]) u_.segment<3>(3 * node) = prescribed_u_[node];
  }
  for (const auto& c : contacts_) {
    // A sliding node (solve_to_convergence() after a step) keeps where it slid to.
    if (sliding_.slides(c.node)) continue;
    held_[c.node] = 1;
    u_.segment<3>(3 * c.node) = c.target_mm - rest_[c.node];
  }
}

Eigen::Matrix3d CorotationalFem::deformation_gradient(int t) const {
  // F = Σ_b (x_b − x_0) g_bᵀ.
  return deformed_edges(tets_[t], rest_, u_)
      .lazyProduct(shape_gradients_[t].rightCols<3>().transpose());
}

void CorotationalFem::extract_rotation(int t, const Eigen::Matrix3d& f) {
  const Eigen::Matrix3d r = polar_rotation(f);
  rotation_[t] = r;
  const auto& g = shape_gradients_[t];
  rotated_gradients_[t].noalias() = r.lazyProduct(g);
  // Element rhs R K_e (x0 − Rᵀ x0): the displacement x0 − Rᵀ x0 has gradient I − Rᵀ, so the
  // nodal forces are R σ(I − sym R) V g_a.
  const Eigen::Matrix3d strain = Eigen::Matrix3d::Identity() - 0.5 * (r + r.transpose());
  element_rhs_[t].noalias() = (r * volume_stress(strain, lame_volume_[t])).lazyProduct(g);
}

void CorotationalFem::update_rotations(double tolerance, int max_updates, int check_interval) {
  const int chunks = tet_chunks();
  // The tets' turns, then those past the tolerance, or the max_updates most turned of them. A
  // tet with no rotation near the one it holds (inverted, collapsed, its symmetric part not
  // positive definite: an infinite turn) takes a new one at every update, outside the cap: ranked
  // first, such tets under a deep press filled the cap, the same ones frame after frame, and no
  // other tet's rotation moved while the probe stayed.
  // A tet found within the tolerance at its last check is checked again once every
  // check_interval updates (a tet past it, lost, or given a new rotation at it: every update): the
  // check is the fixed work's largest part (a stitched sub-volume's 13,720 tets: 0.48 of its
  // 1.7 ms a touched step), and a tet found turned a step later has turned a step further, as
  // one the cap leaves does.
  const int interval = check_every_tet_ ? 1 : std::max(check_interval, 1);
  const int phase = static_cast<int>(turn_check_frame_++ % interval);
  check_every_tet_ = false;
  const auto lost = [](double turn) { return turn == std::numeric_limits<double>::infinity(); };
  // Four tets at a time with AVX2 where the CPU has it: the check is the update's largest fixed
  // part (0.42 ms of a touched 15³ sub-volume's, ~37 ns a tet one at a time).
  const corotational_detail::TurnKernel turns = corotational_detail::fastest_turn_kernel();
  const corotational_detail::TurnInputs inputs{tets_.data(), rest_.data(), u_.data(),
                                               shape_gradients_.data(), rotation_.data()};
  for_each_chunk(chunks, [&](int chunk) {
    const auto [begin, end] = tet_range(chunk);
    std::array<int, kTetsPerChunk> due;  // the chunk's tets to check, in tet order
    int due_count = 0;
    for (int t = begin; t < end; ++t) {
      if (t % interval != phase && turn_[t] < tolerance) continue;
      due[due_count++] = t;
    }
    const std::span<const int> checked(due.data(), due_count);
    turns(inputs, checked, turn_.data());
    int turned = 0, lost_rotations = 0;
    for (const int t : checked) {
      lost_rotations += lost(turn_[t]);
      turned += !(turn_[t] < tolerance) && !lost(turn_[t]);
    }
    chunk_sums_[chunk] = Eigen::Vector4d(turned, lost_rotations, 0.0, 0.0);
  });
  const Eigen::Vector4d counts = sum_chunks(chunks);
  const int turned = static_cast<int>(counts[0]);
  if (turned <= max_updates) {
    for_each_chunk(chunks, [&](int chunk) {
      const auto [begin, end] = tet_range(chunk);
      for (int t = begin; t < end; ++t) rotation_moved_[t] = !(turn_[t] < tolerance);
    });
    rotations_updated_ = turned + static_cast<int>(counts[1]);
  } else {
    // The max_updates most turned: those past the max_updates-th largest finite turn, then of
    // those at it (a regular mesh's twins turn alike) the first in tet order.
    turn_scratch_.clear();  // capacity: every tet
    for (const double turn : turn_) {
      if (!(turn < tolerance) && !lost(turn)) turn_scratch_.push_back(turn);
    }
    const auto nth = turn_scratch_.begin() + (turned - max_updates);
    std::nth_element(turn_scratch_.begin(), nth, turn_scratch_.end());
    const double threshold = *nth;
    int ties_left =
        max_updates - static_cast<int>(std::count_if(
                          nth, turn_scratch_.end(), [&](double turn) { return turn > threshold; }));
    rotations_updated_ = 0;
    for (int t = 0; t < tet_count(); ++t) {
      const bool tie = turn_[t] == threshold && ties_left > 0;
      ties_left -= tie;
      rotation_moved_[t] = turn_[t] > threshold || tie;  // the lost ones' infinite turns too
      rotations_updated_ += rotation_moved_[t];
    }
  }
  prepare_block_updates();  // before the new rotations
  for_each_chunk(chunks, [&](int chunk) {
    const auto [begin, end] = tet_range(chunk);
    for (int t = begin; t < end; ++t) {
      if (!rotation_moved_[t]) continue;
      extract_rotation(t, deformation_gradient(t));
      // Checked again next step (a tet turning under a sliding probe keeps turning), skipped
      // only once found back within the tolerance.
      if (!lost(turn_[t])) turn_[t] = tolerance;
    }
  });
}

void CorotationalFem::keep_rotations() {
  // No row moved: the assembly then updates only what a changed load needs.
  std::fill(node_moved_.begin(), node_moved_.end(), 0);
  rotations_updated_ = 0;
}

int CorotationalFem::rotation_update_cap() const {
  return std::max(1, static_cast<int>(std::ceil(settings_.max_rotation_updates_fraction *
                                                static_cast<double>(tet_count()))));
}

void CorotationalFem::prepare_block_updates() {
  moved_tets_.clear();
  // Swapping a tet's terms reads its own ten blocks; summing its rows again reads every term of
  // the blocks its nodes' rows hold (the planning and the assembly of the block-by-block choice
  // this replaced read them twice: 0.63 of a touched sub-volume's 1.36 ms update in the soak).
  sum_moved_rows_again_ = static_cast<double>(rotations_updated_) >=
                          settings_.term_swap_max_fraction * static_cast<double>(tet_count());
  if (rotations_updated_ == tet_count()) {
    std::fill(node_moved_.begin(), node_moved_.end(), 1);
    return;
  }
  // A node none of whose tets moved keeps every block of its row and its rhs's tet terms. Marked
  // from the moved tets (a few hundred of a stitched sub-volume's 13,720 under the large soak's
  // presses) rather than by asking each node's twenty-odd tets.
  std::fill(node_moved_.begin(), node_moved_.end(), 0);
  for (int t = 0; t < tet_count(); ++t) {
    if (!rotation_moved_[t]) continue;
    if (!sum_moved_rows_again_) moved_tets_.push_back(t);
    for (const int node : tets_[t]) node_moved_[node] = 1;
  }
  add_moved_tets_terms(-1.0);  // with the rotations they still hold
}

void CorotationalFem::add_moved_tets_terms(double sign) {
  // One thread, in tet order: tets sharing a block would race, and the order fixes the sums. A
  // stitched sub-volume's blocks (6.5 MB on 15³) are far from the cache when it steps: each tet's
  // data is fetched ahead, its blocks' (found from that data) two tets ahead.
  const auto fetch = [](const void* p) { __builtin_prefetch(p, 1); };
  const auto row_block = [&](int t, int pair, int row) {
    return &block_value_[block_row_start_[tets_[t][row]] + tet_blocks_[t][pair]];
  };
  const int count = static_cast<int>(moved_tets_.size());
  for (int i = 0; i < count; ++i) {
    if (i + 4 < count) {
      const int ahead = moved_tets_[i + 4];
      fetch(&tets_[ahead]);
      fetch(&tet_blocks_[ahead]);
      fetch(&rotated_gradients_[ahead]);
      fetch(&rotated_gradients_[ahead](0, 3));
      fetch(&element_rhs_[ahead]);
      fetch(&element_rhs_[ahead](0, 3));
      fetch(&lame_volume_[ahead]);
    }
    if (i + 2 < count) {
      const int ahead = moved_tets_[i + 2];
      int pair = 0;
      for (int a = 0; a < 4; ++a) {
        fetch(&rhs_[3 * tets_[ahead][a]]);
        for (int b = a; b < 4; ++b) {
          const Eigen::Matrix3d* block =
              row_block(ahead, pair++, upper_block_pair(tets_[ahead], a, b).first);
          fetch(block);
          fetch(&(*block)(2, 2));
        }
      }
    }
    const int t = moved_tets_[i];
    const auto& tet = tets_[t];
    const auto& g = rotated_gradients_[t];
    int pair = 0;
    for (int a = 0; a < 4; ++a) {
      rhs_.segment<3>(3 * tet[a]) += sign * element_rhs_[t].col(a);
      for (int b = a; b < 4; ++b) {
        const auto [row, col] = upper_block_pair(tet, a, b);
        *row_block(t, pair++, row) +=
            sign * stiffness_block(g.col(row), g.col(col), lame_volume_[t]);
      }
    }
  }
}

void CorotationalFem::assemble_warped_system() {
  add_moved_tets_terms(1.0);  // their old terms were taken out
  moved_tets_.clear();        // a step that keeps its rotations adds nothing
  // A gather over global blocks, row bands in parallel: no two tasks write the same value.
  for_each_chunk(node_chunks(), [&](int chunk) {
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (!node_moved_[node] && !loads_changed_) continue;
      if (node_moved_[node] && sum_moved_rows_again_) {
        // A block changed only if a moved tet holds both its nodes; below the diagonal: the
        // second pass.
        for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
          if (mirror_block_[k] < 0 && node_moved_[block_col_[k]]) {
            block_value_[k] = summed_block(k, rotated_gradients_);
          }
        }
      }
      // Swapped tets swapped their rhs terms too.
      if (loads_changed_ || sum_moved_rows_again_) {
        rhs_.segment<3>(3 * node) = add_element_forces(node, load_mn_.segment<3>(3 * node));
      }
      update_inverse_diagonal(node);
    }
  });
  loads_changed_ = false;
  // Blocks below the diagonal, from the finished blocks above it. A block's tets hold both its
  // nodes: a block with a node that no moved tet holds did not change.
  for_each_chunk(node_chunks(), [&](int chunk) {
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (!node_moved_[node]) continue;
      for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
        const int mirror = mirror_block_[k];
        if (mirror >= 0 && node_moved_[block_col_[k]]) {
          block_value_[k] = block_value_[mirror].transpose();
        }
      }
    }
  });
  update_tissue_product_rows();
}

void CorotationalFem::update_tissue_product_rows() {
  if (!tissue_product_known_) return;
  if (rotations_updated_ == tet_count() || settings_.tissue_product_refresh_steps == 1) {
    tissue_product_known_ = false;  // every block changed, or the reference: a product
    return;
  }
  // A block changes only with a moved tet holding both its nodes: only moved nodes' rows.
  for_each_chunk(node_chunks(), [&](int chunk) {
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (node_moved_[node] && !fixed_[node]) {
        tissue_product_.segment<3>(3 * node) = warped_row_times(node, tissue_product_u_);
      }
    }
  });
}

void CorotationalFem::compute_tissue_product() {
  for_each_chunk(node_chunks(), [&](int chunk) {
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (!fixed_[node]) tissue_product_.segment<3>(3 * node) = warped_row_times(node, u_);
    }
  });
  tissue_product_u_ = u_;
  tissue_product_known_ = true;
  tissue_product_age_ = 0;
}

void CorotationalFem::sync_tissue_product() {
  if (!tissue_product_known_ || ++tissue_product_age_ >= settings_.tissue_product_refresh_steps) {
    compute_tissue_product();
    return;
  }
  moved_nodes_.clear();
  for (int node = 0; node < node_count(); ++node) {
    if (u_.segment<3>(3 * node) != tissue_product_u_.segment<3>(3 * node)) {
      moved_nodes_.push_back(node);
    }
  }
  // A column costs as much as a row: past an eighth of them, a product is as cheap.
  if (moved_nodes_.size() > static_cast<std::size_t>(node_count() / 8)) {
    compute_tissue_product();
    return;
  }
  // One thread, node by node: columns write other chunks' rows, in the same order every time.
  for (const int node : moved_nodes_) {
    const Eigen::Vector3d moved = u_.segment<3>(3 * node) - tissue_product_u_.segment<3>(3 * node);
    for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
      // K is symmetric: column `node` of row j is block (node, j) transposed.
      tissue_product_.segment<3>(3 * block_col_[k]).noalias() +=
          block_value_[k].transpose() * moved;
    }
    tissue_product_u_.segment<3>(3 * node) = u_.segment<3>(3 * node);
  }
}

void CorotationalFem::carry_tissue_product() {
  for_each_chunk(node_chunks(), [&](int chunk) {
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (fixed_[node]) continue;  // held for good: its row never starts a solve
      if (held_[node] || sliding_.slides(node)) {
        tissue_product_.segment<3>(3 * node) = warped_row_times(node, u_);
      } else {
        tissue_product_.segment<3>(3 * node) =
            rhs_.segment<3>(3 * node) + anchor_load_mn_.segment<3>(3 * node) -
            anchor_stiffness_.segment<3>(3 * node).cwiseProduct(u_.segment<3>(3 * node)) -
            r_.segment<3>(3 * node);
      }
    }
  });
  tissue_product_u_ = u_;
}

void CorotationalFem::mark_constrained_rows() {
  // K's pattern is symmetric: the rows with a held or sliding column are that node's neighbours.
  std::fill(meets_constraint_.begin(), meets_constraint_.end(), 0);
  for (int node = 0; node < node_count(); ++node) {
    if (!held_[node] && !sliding_.slides(node)) continue;
    for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
      meets_constraint_[block_col_[k]] = 1;
    }
  }
}

CorotationalFem::PcgResult CorotationalFem::run_pcg(int max_iterations, double tolerance,
                                                    const StepBudget& may_continue) {
  const int chunks = node_chunks();
  mark_constrained_rows();
  sync_tissue_product();
  // Start: r = b − K u on free rows. The free system is K_ff u_f = b_f − K_fh u_h; its rhs norm
  // (the same product restricted to held columns) is the residual's yardstick, so a warm start
  // that is already close does not make the tolerance stricter.
  for_each_chunk(chunks, [&](int chunk) {
    Eigen::Vector4d sums = Eigen::Vector4d::Zero();  // r·r, rhs·rhs, r·z
    const auto [begin, end] = node_range(chunk);
    for (int node = begin; node < end; ++node) {
      if (held_[node]) {
        r_.segment<3>(3 * node).setZero();
        p_.segment<3>(3 * node).setZero();
        continue;
      }
      Eigen::Vector3d ku = Eigen::Vector3d::Zero(), ku_held = Eigen::Vector3d::Zero();
      // Most rows meet no constraint: K u as carried, without a product or a test per block.
      if (!meets_constraint_[node]) {
        ku = tissue_product_.segment<3>(3 * node);
      } else {
        for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
          const int col = block_col_[k];
          const Eigen::Vector3d term = block_value_[k].lazyProduct(u_.segment<3>(3 * col));
          ku += term;
          if (held_[col]) {
            ku_held += term;
          } else if (sliding_.slides(col)) {
            // What the contact holds of a sliding node: its displacement along the normal.
            const Eigen::Vector3d& n = sliding_.hold(col)->normal;
            ku_held.noalias() += block_value_[k] * (n * n.dot(u_.segment<3>(3 * col)));
          }
        }
      }
      // An anchor: k u on the node's own (free) row, k (target − rest) on its rhs.
      ku += anchor_stiffness_.segment<3>(3 * node).cwiseProduct(u_.segment<3>(3 * node));
      const Eigen::Vector3d b = rhs_.segment<3>(3 * node) + anchor_load_mn_.segment<3>(3 * node);
      Eigen::Vector3d r = b - ku;
      Eigen::Vector3d free_rhs = b - ku_held;
      const bool slides = sliding_.slides(node);
      if (slides) {
        // Filtered: the node moves in the probe's tangent plane against its friction.
        r += sliding_.hold(node)->friction_mn;
        free_rhs += sliding_.hold(node)->friction_mn;
        sliding_.project(node, r);
        sliding_.project(node, free_rhs);
      }
      // The first direction is z = M⁻¹ r; z_ is the iterations' own (each computes it from r).
      Eigen::Vector3d z = inverse_diagonal_.segment<3>(3 * node).cwiseProduct(r);
      if (slides) sliding_.project(node, z);
      r_.segment<3>(3 * node) = r;
      p_.segment<3>(3 * node) = z;
      sums += Eigen::Vector4d(r.squaredNorm(), free_rhs.squaredNorm(), r.dot(z), 0.0);
    }
    chunk_sums_[chunk] = sums;
  });
  const Eigen::Vector4d start = sum_chunks(chunks);
  // With nothing pushing (probe lifted, no loads) the answer is rest and the rhs is 0: measure
  // progress against where this frame started instead.
  const double reference = std::max({std::sqrt(start[0]), std::sqrt(start[1]), 1e-30});
  double rz = start[2];
  double residual = std::sqrt(start[0]);
  int it = 0;
  bool cut_short = false;
  while (it < max_iterations && residual > tolerance * reference) {
    if (it > 0 && may_continue && !may_continue()) {
      cut_short = true;
      break;
    }
    // q = K p on free rows; p·q.
    for_each_chunk(chunks, [&](int chunk) {
      double pq = 0.0;
      const auto [begin, end] = node_range(chunk);
      for (int node = begin; node < end; ++node) {
        if (held_[node]) {
          q_.segment<3>(3 * node).setZero();
          continue;
        }
        Eigen::Vector3d kp = warped_row_times(node, p_);
        kp += anchor_stiffness_.segment<3>(3 * node).cwiseProduct(p_.segment<3>(3 * node));
        if (sliding_.slides(node)) sliding_.project(node, kp);
        q_.segment<3>(3 * node) = kp;
        pq += p_.segment<3>(3 * node).dot(kp);
      }
      chunk_sums_[chunk] = Eigen::Vector4d(pq, 0.0, 0.0, 0.0);
    });
    const double pq = sum_chunks(chunks)[0];
    if (!(pq > 0)) break;  // converged to rounding (or non-finite: caught by the caller)
    const double alpha = rz / pq;
    // u += αp, r −= αq, z = M⁻¹ r; r·z, r·r. Held rows have p = q = r = 0 and stay put.
    for_each_chunk(chunks, [&](int chunk) {
      const auto [begin, end] = node_range(chunk);
      const int lo = 3 * begin, len = 3 * (end - begin);
      u_.segment(lo, len) += alpha * p_.segment(lo, len);
      r_.segment(lo, len) -= alpha * q_.segment(lo, len);
      z_.segment(lo, len) = inverse_diagonal_.segment(lo, len).cwiseProduct(r_.segment(lo, len));
      if (chunk_slides_[chunk]) {
        for (int node = begin; node < end; ++node) {
          if (sliding_.slides(node)) sliding_.project(node, z_.segment<3>(3 * node));
        }
      }
      chunk_sums_[chunk] = Eigen::Vector4d(r_.segment(lo, len).dot(z_.segment(lo, len)),
                                           r_.segment(lo, len).squaredNorm(), 0.0, 0.0);
    });
    const Eigen::Vector4d sums = sum_chunks(chunks);
    const double beta = sums[0] / rz;
    rz = sums[0];
    residual = std::sqrt(sums[1]);
    for_each_chunk(chunks, [&](int chunk) {
      const auto [begin, end] = node_range(chunk);
      const int lo = 3 * begin, len = 3 * (end - begin);
      p_.segment(lo, len) = z_.segment(lo, len) + beta * p_.segment(lo, len);
    });
    ++it;
  }
  // The reference (a product every solve) never reads it: its steps are the plain ones.
  if (settings_.tissue_product_refresh_steps > 1) carry_tissue_product();
  return {it, residual / reference, cut_short};
}

template <typename Position>
CorotationalFem::InversionCount CorotationalFem::count_inverted_at(Position position) const {
  const int chunks = tet_chunks();
  for_each_chunk(chunks, [&](int chunk) {
    int inverted = 0, with_free_node = 0;
    const auto [begin, end] = tet_range(chunk);
    for (int t = begin; t < end; ++t) {
      const auto& tet = tets_[t];
      // Not `<= 0`: a NaN volume counts as inverted too.
      const Eigen::Matrix3d edges =
          edge_matrix(position(tet[0]), position(tet[1]), position(tet[2]), position(tet[3]));
      if (edges.determinant() > 0.0) continue;
      ++inverted;
      // On the probe: held, or held along its normal (sliding).
      const auto on_probe = [&](int node) { return held_[node] || sliding_.slides(node); };
      with_free_node +=
          !(on_probe(tet[0]) && on_probe(tet[1]) && on_probe(tet[2]) && on_probe(tet[3]));
    }
    chunk_sums_[chunk] = Eigen::Vector4d(inverted, with_free_node, 0.0, 0.0);
  });
  const Eigen::Vector4d sums = sum_chunks(chunks);
  return {static_cast<int>(sums[0]), static_cast<int>(sums[1])};
}

CorotationalFem::InversionCount CorotationalFem::count_inverted(const Eigen::VectorXd& u) const {
  return count_inverted_at(
      [&](int node) -> Eigen::Vector3d { return rest_[node] + u.segment<3>(3 * node); });
}

CorotationalFem::InversionCount CorotationalFem::count_inverted_deformed() const {
  return count_inverted_at([&](int node) -> const Eigen::Vector3d& { return deformed_[node]; });
}

int CorotationalFem::inverted_tet_count() const {
  return count_inverted(u_).total;
}

double CorotationalFem::measure_contact_forces() {
  // The force the probe exerts on a held node is what its elasticity and load leave unbalanced:
  // K_R u − b (b includes the loads), in mN. Its part along the probe's outward normal is the
  // push the next frame's release test reads.
  std::fill(contact_push_mn_.begin(), contact_push_mn_.end(), 0.0);
  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (const auto& c : contacts_) {
    const Eigen::Vector3d force_mn = node_force_mn(c.node);
    contact_push_mn_[c.node] = force_mn.dot(c.normal);
    // A sliding node: its push and friction only (LinearFem::update_contact_forces says why).
    total_mn += sliding_.slides(c.node) ? sliding_.probe_force_mn(c.node, force_mn) : force_mn;
  }
  return total_mn.norm() / 1000.0;
}

int CorotationalFem::inversion_limit() const {
  // The same tolerance as the other engines (`inverted > fraction × tets` fails a frame).
  return static_cast<int>(
      std::floor(settings_.max_inverted_fraction * static_cast<double>(tet_count())));
}

void CorotationalFem::accept_or_recover(EngineStepStats& stats, const StepBudget& may_continue) {
  const bool finite = u_.allFinite();
  const InversionCount inverted = finite ? count_inverted_deformed() : InversionCount{};
  stats.inverted_tets = inverted.total;
  // Tets whose four nodes are all on the probe (pressed flat between probe contacts) are the
  // constraints' doing, which no solve or retry changes: only the others count against a frame.
  // A few of those are the linear element's weakness under the probe's rounded rim, not a
  // failed frame: refusing every such frame made the tissue lag a sliding probe on most frames.
  if (finite && inverted.with_free_node <= inversion_limit()) return;
  // A shape that starts over the limit (handed over folded by another engine) may keep its folds
  // while the frames unfold it, but not add to them: without this allowance every frame would
  // be thrown away and the shape would stay folded for good.
  const InversionCount at_start = count_inverted(u_before_step_);
  const int allowed = std::max(inversion_limit(), at_start.with_free_node);
  if (finite && inverted.with_free_node <= allowed) return;
  stats.diverged = true;
  stats.cause = finite ? DivergenceCause::kInverted : DivergenceCause::kNonFinite;
  stats.recovery = Recovery::kSubstepped;
  if (!finite) tissue_product_known_ = false;  // carried from a non-finite residual
  if (finite) {
    // Cut the frame's update short: the tissue lags the probe for a frame instead of folding.
    q_ = u_ - u_before_step_;
    double fraction = 1.0;
    for (int i = 0; i < kMaxBacktracks; ++i) {
      // Each try recounts every tet's volume (a deep press's refused frames took ten): once the
      // frame's time is spent, the previous shape at once, and the next frame tries again.
      if (may_continue && !may_continue()) {
        stats.cut_short = true;
        break;
      }
      fraction *= 0.5;
      u_ = u_before_step_ + fraction * q_;
      const InversionCount cut = count_inverted(u_);
      if (cut.with_free_node <= allowed) {
        stats.inverted_tets = cut.total;  // what is shown
        update_deformed();
        return;
      }
    }
  }
  // All the way back: the previous frame's shape. Not rest, which with the probe still deep in
  // the tissue would put nodes far inside it and start from a worse shape than this.
  u_ = u_before_step_;
  stats.inverted_tets = at_start.total;
  update_deformed();
}

void CorotationalFem::update_deformed() {
  for (int node = 0; node < node_count(); ++node) {
    deformed_[node] = rest_[node] + u_.segment<3>(3 * node);
  }
}

bool CorotationalFem::update_forced_at(std::int64_t step) const {
  const bool due =
      step % settings_.rotation_update_interval_frames == settings_.rotation_update_phase;
  return check_every_tet_ || (due && updates_held_in_a_row_ >= settings_.max_update_turns_held);
}

EngineStepStats CorotationalFem::step(const ProbeCollider* probe, double frame_dt_s) {
  return step_within(probe, frame_dt_s, {});
}

EngineStepStats CorotationalFem::step_within(const ProbeCollider* probe, double /*frame_dt_s*/,
                                             const StepBudget& may_continue) {
  u_before_step_ = u_;
  apply_constraints(probe);
  const int update_interval = settings_.rotation_update_interval_frames;
  const bool due = step_count_ % update_interval == settings_.rotation_update_phase;
  update_held_ = due && hold_next_update_ && !check_every_tet_ &&
                 updates_held_in_a_row_ < settings_.max_update_turns_held;
  hold_next_update_ = false;
  warped_system_updated_ = check_every_tet_ || (due && !update_held_);
  if (update_held_) ++updates_held_in_a_row_;
  if (warped_system_updated_) updates_held_in_a_row_ = 0;
  warped_system_updates_ += warped_system_updated_;
  if (warped_system_updated_) {
    update_rotations(settings_.rotation_update_tolerance, rotation_update_cap(),
                     settings_.turn_check_interval_frames);
  } else {
    keep_rotations();
  }
  ++step_count_;
  assemble_warped_system();
  const PcgResult pcg =
      run_pcg(settings_.pcg_iterations_per_frame, settings_.relative_tolerance, may_continue);
  EngineStepStats stats;
  stats.cut_short = pcg.cut_short;
  stats.iterations = pcg.iterations;
  stats.relative_residual = pcg.relative_residual;
  stats.contact_nodes = static_cast<int>(contacts_.size());
  // A diverged step's held update counts toward the limit as any other, so the bound holds.
  // Taking the next due update whatever the time after one (tried) doubled the large soak's
  // diverged frames (313 against 146) and its corotational late frames (129 against 55).
  update_deformed();
  accept_or_recover(stats, may_continue);
  stats.contact_force_n = measure_contact_forces();
  return stats;
}

CorotationalConvergence CorotationalFem::solve_to_convergence(double tolerance_mm, int max_outer) {
  CorotationalConvergence result;
  hold_next_update_ = false;  // asked of a step, not of the reference
  // The last step's contacts stay held at their targets: re-apply them, since a cut-short
  // frame may have left them short.
  hold_constrained_nodes();
  const Eigen::VectorXd::Index dofs = u_.size();
  const int max_pcg =
      static_cast<int>(2 * dofs + 100);  // CG needs ≤ dofs steps, in exact arithmetic
  PcgResult pcg;
  while (result.outer_iterations < max_outer) {
    u_before_step_ = u_;                    // the shape this outer iteration starts from
    update_rotations(0.0, tet_count(), 1);  // the reference: every rotation exact
    assemble_warped_system();
    pcg = run_pcg(max_pcg, kConvergedRelativeResidual, {});
    result.pcg_iterations += pcg.iterations;
    ++result.outer_iterations;
    if (!u_.allFinite()) break;
    double change = 0.0;
    for (int node = 0; node < node_count(); ++node) {
      change =
          std::max(change, (u_.segment<3>(3 * node) - u_before_step_.segment<3>(3 * node)).norm());
    }
    result.last_change_mm = change;
    if (change < tolerance_mm) {
      result.converged = true;
      break;
    }
  }
  // The reference keeps its converged shape, inverted tets and all (they are reported: a
  // backtracked answer would not be the converged one); only a non-finite one is thrown away.
  EngineStepStats& stats = result.stats;
  stats.iterations = result.pcg_iterations;
  stats.relative_residual = pcg.relative_residual;
  stats.contact_nodes = static_cast<int>(contacts_.size());
  if (!u_.allFinite()) {
    u_ = u_before_step_;  // the last finite iterate
    stats.diverged = true;
    stats.cause = DivergenceCause::kNonFinite;
    stats.recovery = Recovery::kSubstepped;
    result.converged = false;
  } else {
    const InversionCount inverted = count_inverted(u_);
    stats.inverted_tets = inverted.total;
    stats.diverged = inverted.with_free_node > inversion_limit();  // as step() would judge it
    if (stats.diverged) stats.cause = DivergenceCause::kInverted;
    stats.contact_force_n = measure_contact_forces();
  }
  update_deformed();
  return result;
}

void CorotationalFem::elastic_forces_mn(std::span<const Eigen::Vector3d> positions_mm,
                                        Eigen::VectorXd& forces_mn) const {
  if (positions_mm.size() != rest_.size()) {
    throw std::invalid_argument("CorotationalFem::elastic_forces_mn: need one position per node");
  }
  forces_mn.setZero(3 * node_count());
  for (int t = 0; t < tet_count(); ++t) {
    const auto& tet = tets_[t];
    const auto& x = positions_mm;
    const auto& g = shape_gradients_[t];
    const Eigen::Matrix3d f =
        edge_matrix(x[tet[0]], x[tet[1]], x[tet[2]], x[tet[3]]) * g.rightCols<3>().transpose();
    const Eigen::Matrix3d r = polar_rotation(f);
    // R K_e (Rᵀ x − x0): the field Rᵀ x − x0 has gradient Rᵀ F − I (symmetric for the polar R).
    const Eigen::Matrix3d rtf = r.transpose() * f;
    const Eigen::Matrix3d strain = 0.5 * (rtf + rtf.transpose()) - Eigen::Matrix3d::Identity();
    const Eigen::Matrix<double, 3, 4> nodal = r * volume_stress(strain, lame_volume_[t]) * g;
    for (int a = 0; a < 4; ++a) forces_mn.segment<3>(3 * tet[a]) += nodal.col(a);
  }
}

Eigen::SparseMatrix<double, Eigen::RowMajor> CorotationalFem::warped_stiffness() const {
  return node_blocks_as_matrix(block_value_);
}

Eigen::SparseMatrix<double, Eigen::RowMajor> CorotationalFem::node_blocks_as_matrix(
    const std::vector<Eigen::Matrix3d>& blocks) const {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(blocks.size() * 9);
  for (int node = 0; node < node_count(); ++node) {
    for (int k = block_row_start_[node]; k < block_row_start_[node + 1]; ++k) {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          triplets.emplace_back(3 * node + i, 3 * block_col_[k] + j, blocks[k](i, j));
        }
      }
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> k(3 * node_count(), 3 * node_count());
  k.setFromTriplets(triplets.begin(), triplets.end());
  return k;
}

}  // namespace ultrasim::sim
