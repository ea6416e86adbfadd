#include "ultrasim/sim/exact_fem.hpp"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <string>

#include "model_checks.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::sim {

struct ExactFem::Factor {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  // CHOLMOD's solve writes workspace inside `llt`: one solve at a time, frame or background.
  std::mutex mutex;

  // K⁻¹'s three columns at `node`'s DOFs (n_free × 3). Allocates.
  Columns columns_at(int node, const std::vector<int>& global_to_free) {
    Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(llt.rows()), 3);
    for (int i = 0; i < 3; ++i) unit(global_to_free[3 * node + i], i) = 1.0;
    std::lock_guard lock(mutex);
    return llt.solve(unit);
  }
};

// One node's Green's functions solved on the job system's background thread: a budgeted frame
// defers a node it has none for, the background solves it beside the frames, and a later frame
// takes the columns into the cache.
struct ExactFem::BackgroundSolve {
  enum class State { kIdle, kQueued, kDone };
  Factor* factor = nullptr;
  const std::vector<int>* global_to_free = nullptr;
  std::mutex mutex;
  std::condition_variable done;
  State state = State::kIdle;  // under `mutex`
  int node = -1;               // written before posting, read by the background thread
  Columns columns;             // the background thread's result

  static void run(void* self) {
    auto& solve = *static_cast<BackgroundSolve*>(self);
    Columns columns = solve.factor->columns_at(solve.node, *solve.global_to_free);
    // Notified under the lock: the engine's destructor, woken by it, cannot free `done` before
    // this thread has let go of the mutex, its last touch of the engine.
    std::lock_guard lock(solve.mutex);
    solve.columns.swap(columns);
    solve.state = State::kDone;
    solve.done.notify_all();
  }
};

namespace {

// Nodes per block of right-hand sides when precomputing Green's functions: CHOLMOD's supernodal
// solve is fastest per column at ~16 columns (measured: 1.5 ms/column at 32×16×16 nodes against
// 4.1 ms one at a time and 2.3 ms at 64).
constexpr int kNodesPerSolveBlock = 5;

// Rows of the free-DOF vector per task of the parallel field update.
constexpr int kFieldBand = 4096;

// A node kept on the probe's surface this close counts as touching (mm): a node left exactly on
// the surface by the last frame must not flicker in and out of contact.
constexpr double kTouchToleranceMm = 1e-9;

// A node this close to the probe's surface counts as on it (mm). Held nodes slide along tangent
// planes, so on the probe's curved rim each round re-projects them; 10 µm (a tenth of a B-scan
// pixel at 40 mm depth) ends that in a few rounds instead of creeping on for many; each frame
// re-projects them again from where they are, so under a held probe they creep on to their
// equilibrium on the rim over frames, a round a frame.
constexpr double kSurfaceToleranceMm = 0.01;

// Constraint forces below this (mN) are rounding, not pulling.
constexpr double kPullToleranceMn = 1e-9;

}  // namespace

ExactFem::ExactFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
                   std::span<const std::uint8_t> fixed_nodes, const ExactFemSettings& settings,
                   std::span<const std::uint8_t> contact_candidates, hal::JobSystem* jobs)
    : settings_(settings),
      jobs_(jobs),
      rest_(mesh.rest_positions_mm),
      tets_(mesh.tets),
      fixed_(fixed_nodes.begin(), fixed_nodes.end()),
      factor_(std::make_unique<Factor>()),
      background_(std::make_unique<BackgroundSolve>()),
      node_slot_(mesh.rest_positions_mm.size(), -1),
      node_constrained_index_(mesh.rest_positions_mm.size(), -1),
      in_contact_(mesh.rest_positions_mm.size(), 0),
      released_(mesh.rest_positions_mm.size(), 0),
      deferred_(mesh.rest_positions_mm.size(), 0),
      deformed_(mesh.rest_positions_mm) {
  // The same model and stiffness as LinearFem: one model, two solvers.
  check_tet_model("ExactFem", mesh, tet_materials, fixed_nodes);
  stiffness_ = assemble_stiffness(mesh, tet_materials);
  if (settings.max_cached_nodes < 0) {
    throw std::invalid_argument("ExactFem: max_cached_nodes must be >= 0");
  }
  if (!(settings.max_inverted_fraction >= 0.0 && settings.max_inverted_fraction <= 1.0)) {
    throw std::invalid_argument("ExactFem: max_inverted_fraction must be in [0, 1]");
  }
  if (settings.max_contact_rounds < 1) {
    throw std::invalid_argument("ExactFem: max_contact_rounds must be >= 1");
  }
  if (!contact_candidates.empty() && contact_candidates.size() != rest_.size()) {
    throw std::invalid_argument("ExactFem: contact_candidates must have one flag per node");
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
  factor_->llt.compute(k_free);
  ++factorizations_;
  if (factor_->llt.info() != Eigen::Success) {
    throw std::invalid_argument(
        "ExactFem: the stiffness on the free DOFs is singular (not positive definite): a part of "
        "the mesh is not held by any fixed node");
  }

  load_mn_ = Eigen::VectorXd::Zero(dofs);
  load_response_ = Eigen::VectorXd::Zero(n_free);
  u_ = Eigen::VectorXd::Zero(dofs);
  last_good_u_ = u_;
  u_free_ = Eigen::VectorXd::Zero(n_free);
  rhs_free_ = Eigen::VectorXd::Zero(n_free);
  precompute_candidates(contact_candidates);
  background_->factor = factor_.get();
  background_->global_to_free = &global_to_free_;
}

ExactFem::~ExactFem() {
  // A queued or running background solve uses the factor and writes into background_.
  std::unique_lock lock(background_->mutex);
  background_->done.wait(lock,
                         [&] { return background_->state != BackgroundSolve::State::kQueued; });
}

void ExactFem::precompute_candidates(std::span<const std::uint8_t> contact_candidates) {
  candidate_slot_.assign(rest_.size(), -1);
  for (int node = 0; node < static_cast<int>(contact_candidates.size()); ++node) {
    if (!contact_candidates[node] || fixed_[node]) continue;
    candidate_slot_[node] = static_cast<int>(candidate_nodes_.size());
    candidate_nodes_.push_back(node);
  }
  const int n_free = free_dof_count();
  const int count = static_cast<int>(candidate_nodes_.size());
  candidate_green_.resize(n_free, 3 * count);
  candidate_compliance_.resize(3 * count, 3 * count);
  Eigen::MatrixXd unit, columns;
  for (int first = 0; first < count; first += kNodesPerSolveBlock) {
    const int nodes = std::min(kNodesPerSolveBlock, count - first);
    unit.setZero(n_free, 3 * nodes);
    for (int k = 0; k < nodes; ++k) {
      for (int i = 0; i < 3; ++i) {
        unit(global_to_free_[3 * candidate_nodes_[first + k] + i], 3 * k + i) = 1.0;
      }
    }
    columns = factor_->llt.solve(unit);
    candidate_green_.middleCols(3 * first, 3 * nodes) = columns.cast<float>();
    for (int c = 0; c < count; ++c) {
      for (int i = 0; i < 3; ++i) {
        candidate_compliance_.block(3 * c + i, 3 * first, 1, 3 * nodes) =
            columns.row(global_to_free_[3 * candidate_nodes_[c] + i]);
      }
    }
  }
  total_columns_computed_ += 3LL * count;
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
  // K u − f: the constraint force on a held node, the support's on a fixed one, ~0 elsewhere.
  Eigen::Vector3d r;
  for (int i = 0; i < 3; ++i) r[i] = stiffness_.row(3 * node + i).dot(u_) - load_mn_[3 * node + i];
  return r;
}

void ExactFem::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != u_.size()) {
    throw std::invalid_argument("ExactFem::set_displacements_mm: expected " +
                                std::to_string(u_.size()) + " values, got " +
                                std::to_string(u_mm.size()));
  }
  u_ = u_mm;
  for (int node = 0; node < node_count(); ++node) {
    if (fixed_[node]) u_.segment<3>(3 * node).setZero();
  }
  last_good_u_ = u_;
  forget_contacts();
  update_deformed();
}

void ExactFem::refresh_load_response(ExactFemStepStats& stats) {
  if (!loads_dirty_) return;
  for (int f = 0; f < free_dof_count(); ++f) rhs_free_[f] = load_mn_[free_to_global_[f]];
  {
    std::lock_guard lock(factor_->mutex);
    load_response_ = factor_->llt.solve(rhs_free_);
  }
  loads_dirty_ = false;
  stats.load_solves = 1;
}

void ExactFem::ensure_columns(int node, ExactFemStepStats& stats) {
  if (candidate_slot_[node] >= 0) {
    stats.columns_reused += 3;
    return;
  }
  if (node_slot_[node] >= 0) {
    stats.columns_reused += 3;
    last_use_[node_slot_[node]] = frame_;
    return;
  }
  const int slot = take_cache_slot(node);
  cache_columns_[slot] = factor_->columns_at(node, global_to_free_);
  stats.columns_computed += 3;
  total_columns_computed_ += 3;
}

int ExactFem::take_cache_slot(int node) {
  int slot = -1;
  if (static_cast<int>(cache_slot_node_.size()) >= settings_.max_cached_nodes) {
    // Evict the least recently used node not held this frame (those carry frame_).
    int oldest = frame_;
    for (int s = 0; s < static_cast<int>(cache_slot_node_.size()); ++s) {
      if (last_use_[s] < oldest) {
        oldest = last_use_[s];
        slot = s;
      }
    }
    if (slot >= 0) node_slot_[cache_slot_node_[slot]] = -1;
  }
  if (slot < 0) {
    slot = static_cast<int>(cache_slot_node_.size());
    cache_slot_node_.push_back(-1);
    cache_columns_.emplace_back();
    last_use_.push_back(0);
  }
  cache_slot_node_[slot] = node;
  node_slot_[node] = slot;
  last_use_[slot] = frame_;
  return slot;
}

void ExactFem::adopt_background_solve() {
  std::lock_guard lock(background_->mutex);
  if (background_->state != BackgroundSolve::State::kDone) return;
  background_->state = BackgroundSolve::State::kIdle;
  const int node = background_->node;
  // An unbudgeted frame may have computed the same columns meanwhile.
  if (candidate_slot_[node] >= 0 || node_slot_[node] >= 0) return;
  cache_columns_[take_cache_slot(node)].swap(background_->columns);
  total_columns_computed_ += 3;
}

void ExactFem::request_background_solve(int node) {
  if (jobs_ == nullptr) return;
  {
    std::lock_guard lock(background_->mutex);
    if (background_->state != BackgroundSolve::State::kIdle) return;
    background_->node = node;
    background_->state = BackgroundSolve::State::kQueued;
  }
  if (!jobs_->post_background(&BackgroundSolve::run, background_.get())) {
    std::lock_guard lock(background_->mutex);
    background_->state = BackgroundSolve::State::kIdle;  // no background thread, or it is busy
  }
}

Eigen::Matrix3d ExactFem::green_block(int a, int b) const {
  const int ca = candidate_slot_[a], cb = candidate_slot_[b];
  Eigen::Matrix3d block;
  if (ca >= 0 && cb >= 0) return candidate_compliance_.block<3, 3>(3 * ca, 3 * cb);
  if (cb < 0) {
    const auto& columns = cache_columns_[node_slot_[b]];
    for (int i = 0; i < 3; ++i) block.row(i) = columns.row(global_to_free_[3 * a + i]);
    return block;
  }
  // K⁻¹ is symmetric: the block is the transpose of a's columns read at b's rows.
  const auto& columns = cache_columns_[node_slot_[a]];
  for (int j = 0; j < 3; ++j) block.col(j) = columns.row(global_to_free_[3 * b + j]).transpose();
  return block;
}

ExactFemStepStats ExactFem::solve(std::span<const PrescribedNode> held) {
  rows_.clear();
  forget_contacts();
  for (const auto& h : held) {
    if (h.node < 0 || h.node >= node_count()) {
      throw std::out_of_range("ExactFem::solve: node " + std::to_string(h.node) + " out of range");
    }
    if (fixed_[h.node]) continue;
    for (int i = 0; i < 3; ++i) {
      rows_.push_back({h.node, Eigen::Vector3d::Unit(i), h.displacement_mm[i]});
    }
  }
  ExactFemStepStats stats = solve_rows(Field::kWhole);
  // Held DOFs equal their targets to rounding; write the targets so they are exact.
  for (const auto& h : held) {
    if (!fixed_[h.node]) u_.segment<3>(3 * h.node) = h.displacement_mm;
  }
  update_deformed();
  return stats;
}

ExactFemStepStats ExactFem::solve(std::span<const NormalConstraint> constraints) {
  rows_.clear();
  forget_contacts();
  for (const auto& c : constraints) {
    if (c.node < 0 || c.node >= node_count()) {
      throw std::out_of_range("ExactFem::solve: node " + std::to_string(c.node) + " out of range");
    }
    if (fixed_[c.node]) continue;
    rows_.push_back({c.node, c.normal.normalized(), c.displacement_mm});
  }
  return solve_rows(Field::kWhole);
}

bool ExactFem::defers(int node) {
  if (!defer_uncached_ || candidate_slot_[node] >= 0 || node_slot_[node] >= 0) return false;
  deferred_[node] = 1;
  return true;
}

ExactFemStepStats ExactFem::solve_rows(Field field) {
  if (defer_uncached_) {
    std::erase_if(rows_, [this](const Row& row) { return defers(row.node); });
  }
  ExactFemStepStats stats;
  ++frame_;
  for (int node : row_nodes_) node_constrained_index_[node] = -1;
  row_nodes_.clear();
  for (const auto& row : rows_) {
    if (node_constrained_index_[row.node] >= 0) continue;
    node_constrained_index_[row.node] = static_cast<int>(row_nodes_.size());
    row_nodes_.push_back(row.node);
    // Nodes already cached and held again this frame must not be evicted by new ones.
    if (node_slot_[row.node] >= 0) last_use_[node_slot_[row.node]] = frame_;
  }
  refresh_load_response(stats);
  for (int node : row_nodes_) ensure_columns(node, stats);

  // Capacitance system (Eᵀ K⁻¹ E) λ = d − Eᵀ K⁻¹ f: Eᵀ K⁻¹ E is SPD when the rows are
  // independent (distinct nodes, or distinct axes at one node).
  const int m = static_cast<int>(rows_.size());
  capacitance_.resize(m, m);
  rhs_.resize(m);
  for (int j = 0; j < m; ++j) {
    const Row& rj = rows_[j];
    Eigen::Vector3d response;
    for (int i = 0; i < 3; ++i) response[i] = load_response_[global_to_free_[3 * rj.node + i]];
    rhs_[j] = rj.value_mm - rj.direction.dot(response);
    for (int k = 0; k <= j; ++k) {
      const Row& rk = rows_[k];
      capacitance_(j, k) = rj.direction.dot(green_block(rj.node, rk.node) * rk.direction);
      capacitance_(k, j) = capacitance_(j, k);
    }
  }
  lambda_mn_.resize(m);
  node_force_mn_.assign(row_nodes_.size(), Eigen::Vector3d::Zero());
  if (m > 0) {
    capacitance_llt_.compute(capacitance_);
    if (capacitance_llt_.info() != Eigen::Success) {
      throw std::invalid_argument(
          "ExactFem::solve: capacitance matrix not positive definite (a node listed twice?)");
    }
    lambda_mn_ = capacitance_llt_.solve(rhs_);
    for (int j = 0; j < m; ++j) {
      node_force_mn_[node_constrained_index_[rows_[j].node]] += rows_[j].direction * lambda_mn_[j];
    }
  }
  if (field == Field::kWhole) {
    update_whole_field();
  } else {
    update_skin_field();
  }

  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (const auto& f : node_force_mn_) total_mn += f;
  stats.contact_nodes = static_cast<int>(row_nodes_.size());
  stats.condensed_size = m;
  stats.contact_force_n = total_mn.norm() / 1000.0;
  stats.contact_rounds = 1;
  last_stats_ = stats;
  return stats;
}

void ExactFem::update_whole_field() {
  accumulate_field();
  u_.setZero();
  for (int f = 0; f < free_dof_count(); ++f) u_[free_to_global_[f]] = u_free_[f];
  update_deformed();
}

void ExactFem::update_skin_field() {
  // Only where the next contact round looks: the candidates and the constrained nodes. From the
  // double compliance blocks, so these positions are those of the whole field to float rounding.
  auto update_node = [&](int node) {
    Eigen::Vector3d u;
    for (int i = 0; i < 3; ++i) u[i] = load_response_[global_to_free_[3 * node + i]];
    for (std::size_t a = 0; a < row_nodes_.size(); ++a) {
      u += green_block(node, row_nodes_[a]) * node_force_mn_[a];
    }
    u_.segment<3>(3 * node) = u;
    deformed_[node] = rest_[node] + u;
  };
  for (int node : candidate_nodes_) update_node(node);
  for (int node : row_nodes_) {
    if (candidate_slot_[node] < 0) update_node(node);
  }
}

void ExactFem::accumulate_field() {
  const int n_free = free_dof_count();
  const int bands = (n_free + kFieldBand - 1) / kFieldBand;
  auto band = [&](int b) {
    const int lo = b * kFieldBand, hi = std::min(n_free, lo + kFieldBand);
    double* u = u_free_.data();
    const double* r = load_response_.data();
    for (int i = lo; i < hi; ++i) u[i] = r[i];
    for (std::size_t a = 0; a < row_nodes_.size(); ++a) {
      const int node = row_nodes_[a];
      const Eigen::Vector3d& w = node_force_mn_[a];
      const int c = candidate_slot_[node];
      if (c >= 0) {
        const float* g0 = candidate_green_.col(3 * c).data();
        const float* g1 = candidate_green_.col(3 * c + 1).data();
        const float* g2 = candidate_green_.col(3 * c + 2).data();
        for (int i = lo; i < hi; ++i) u[i] += g0[i] * w[0] + g1[i] * w[1] + g2[i] * w[2];
      } else {
        const auto& columns = cache_columns_[node_slot_[node]];
        const double* g0 = columns.col(0).data();
        const double* g1 = columns.col(1).data();
        const double* g2 = columns.col(2).data();
        for (int i = lo; i < hi; ++i) u[i] += g0[i] * w[0] + g1[i] * w[1] + g2[i] * w[2];
      }
    }
  };
  hal::parallel_for(jobs_, bands, band);
}

EngineStepStats ExactFem::step_frictionless(const ProbeCollider& probe,
                                            const StepBudget& may_continue) {
  // Start from the last frame's contacts and the nodes now on or inside the probe; then rounds of
  // "release the nodes the probe would have to pull, re-project the ones that slid off its curved
  // rim, take in the nodes that end up inside". Rounds update only the skin (candidates) and the
  // held nodes; the whole field follows once they settle, and a last look over every node takes
  // in any non-skin node pushed inside (another round if so).
  start_from_last_contacts(probe);
  ExactFemStepStats stats;
  int round = 0;
  bool whole_field = false, out_of_time = false;
  while (true) {
    const bool last_round = round + 1 >= settings_.max_contact_rounds;
    const ExactFemStepStats s = solve_rows(last_round ? Field::kWhole : Field::kSkin);
    whole_field = last_round;
    ++round;
    stats.columns_computed += s.columns_computed;
    stats.columns_reused += s.columns_reused;
    stats.load_solves += s.load_solves;
    stats.contact_nodes = s.contact_nodes;
    stats.condensed_size = s.condensed_size;
    stats.contact_force_n = s.contact_force_n;
    if (last_round) break;
    ActiveSetChange change = update_active_set(probe, /*skin_only=*/true);
    if (!change.any()) {
      update_whole_field();
      whole_field = true;
      change = update_active_set(probe, /*skin_only=*/false);
      if (!change.any()) break;
    }
    // Another round. After one that let nodes go, always: no frame shows the probe pulling the
    // skin (a lifted probe would take it up with it). After the others, while there is time: a
    // frame out of time shows this round's answer (the nodes it took in still inside the probe,
    // those it re-projected off its rim) and the next carries on from its set.
    if (!change.released && may_continue && !may_continue()) {
      out_of_time = true;
      break;
    }
  }
  if (!whole_field) update_whole_field();
  // Where the rounds stopped, for the next frame: the set and, if they stopped for time, which
  // nodes they let go (so frames out of time carry on the rounds instead of repeating them).
  last_contacts_.clear();
  for (const Row& row : rows_) last_contacts_.push_back(row.node);
  rounds_unfinished_ = out_of_time;
  stats.contact_rounds = round;
  last_stats_ = stats;
  EngineStepStats out;
  out.iterations = round;
  out.cut_short = out_of_time;
  out.contact_nodes = stats.contact_nodes;
  out.contact_force_n = stats.contact_force_n;
  return out;
}

ExactFem::Row ExactFem::tangent_plane_row(int node, const Eigen::Vector3d& point_mm,
                                          const Eigen::Vector3d& normal) const {
  return {node, normal, normal.dot(point_mm - rest_[node])};
}

void ExactFem::forget_contacts() {
  last_contacts_.clear();
  std::fill(released_.begin(), released_.end(), 0);
  rounds_unfinished_ = false;
}

void ExactFem::start_from_last_contacts(const ProbeCollider& probe) {
  // The nodes held when the last step ended, each at the probe's surface closest to where it is
  // now: a probe held still finds its set settled, a moving one nearly so, instead of redoing
  // the rounds from the nodes that touch it (up to all 8 on a held probe's 40-60 nodes).
  rows_.clear();
  std::fill(in_contact_.begin(), in_contact_.end(), 0);
  for (int node : last_contacts_) {
    const SurfacePoint surface = probe.closest_surface_point(deformed_[node]);
    rows_.push_back(tangent_plane_row(node, surface.point_mm, surface.normal));
    in_contact_[node] = 1;
  }
  // And the nodes on or inside it now, but for those let go before that are still only on its
  // surface: held again, they would be let go again, a round every other frame under a still
  // probe. They stay let go while they stay there.
  find_contacts(probe, deformed_, fixed_, kSurfaceToleranceMm, contacts_);
  still_let_go_.clear();
  for (const auto& c : contacts_) {
    if (in_contact_[c.node]) continue;
    if (released_[c.node] && c.depth_mm <= kSurfaceToleranceMm) {
      still_let_go_.push_back(c.node);
      continue;
    }
    rows_.push_back(tangent_plane_row(c.node, c.target_mm, c.normal));
    in_contact_[c.node] = 1;
  }
  if (!rounds_unfinished_) {
    std::fill(released_.begin(), released_.end(), 0);
    for (int node : still_let_go_) released_[node] = 1;
  }
}

ExactFem::ActiveSetChange ExactFem::update_active_set(const ProbeCollider& probe, bool skin_only) {
  ActiveSetChange change;
  for (const auto& row : rows_) in_contact_[row.node] = 1;
  std::size_t kept = 0;
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const int node = rows_[j].node;
    // The probe would pull this node: let it go, once. A node that falls back into the probe
    // stays held: on a curved rim the plane constraint can flip between the two otherwise.
    if (lambda_mn_[static_cast<Eigen::Index>(j)] < -kPullToleranceMn && !released_[node]) {
      released_[node] = 1;
      in_contact_[node] = 0;
      change.released = true;
      continue;
    }
    // A held node slides along its tangent plane; on a curved part of the probe that leaves it
    // off the surface: hold it at the closest surface point from where it is now instead.
    Row& row = rows_[kept++];
    row = rows_[j];
    const Eigen::Vector3d& p = deformed_[node];
    const SurfacePoint surface = probe.closest_surface_point(p);
    if (std::abs((p - surface.point_mm).dot(surface.normal)) > kSurfaceToleranceMm) {
      row = tangent_plane_row(node, surface.point_mm, surface.normal);
      change.reprojected = true;
    }
  }
  rows_.resize(kept);
  // Nodes pushed into the probe by their neighbours: the closest surface point, as above.
  auto take_in_if_inside = [&](int node) {
    if (in_contact_[node] || fixed_[node] || deferred_[node]) return;
    const SurfacePoint surface = probe.closest_surface_point(deformed_[node]);
    if ((deformed_[node] - surface.point_mm).dot(surface.normal) < -kSurfaceToleranceMm) {
      in_contact_[node] = 1;
      rows_.push_back(tangent_plane_row(node, surface.point_mm, surface.normal));
      change.taken_in = true;
    }
  };
  if (skin_only) {
    for (int node : candidate_nodes_) take_in_if_inside(node);
  } else {
    for (int node = 0; node < node_count(); ++node) take_in_if_inside(node);
  }
  return change;
}

EngineStepStats ExactFem::step(const ProbeCollider* probe, double frame_dt_s) {
  return step_within(probe, frame_dt_s, {});
}

EngineStepStats ExactFem::step_within(const ProbeCollider* probe, double /*frame_dt_s*/,
                                      const StepBudget& may_continue) {
  // One node's Green's functions are a full solve with the factor (~30 ms at 9k nodes): more
  // than a frame's budget ever holds, so under a budget none is computed on the frame, and a
  // node without them is not held; the job system's background thread, where there is one,
  // solves for one such node at a time. The budget is asked between contact rounds.
  defer_uncached_ = static_cast<bool>(may_continue);
  // Later unbudgeted steps compute what they need, even if this one throws.
  struct Reset {
    bool& flag;
    ~Reset() { flag = false; }
  } reset{defer_uncached_};
  std::fill(deferred_.begin(), deferred_.end(), 0);
  adopt_background_solve();
  last_good_u_ = u_;
  EngineStepStats out = solve_probe(probe, may_continue);
  const auto first_deferred = std::find(deferred_.begin(), deferred_.end(), 1);
  const bool deferred_any = first_deferred != deferred_.end();
  out.cut_short = out.cut_short || deferred_any;
  if (deferred_any) request_background_solve(static_cast<int>(first_deferred - deferred_.begin()));
  return out;
}

EngineStepStats ExactFem::solve_probe(const ProbeCollider* probe, const StepBudget& may_continue) {
  EngineStepStats out;
  if (probe == nullptr || settings_.contact != ContactModel::kFrictionless) forget_contacts();
  if (probe == nullptr) {
    rows_.clear();
    solve_rows(Field::kWhole);
    out.iterations = 1;
  } else if (settings_.contact == ContactModel::kFrictionless) {
    out = step_frictionless(*probe, may_continue);
  } else {
    find_contacts(*probe, deformed_, fixed_, kTouchToleranceMm, contacts_);
    rows_.clear();
    for (const auto& c : contacts_) {
      const Eigen::Vector3d target = c.target_mm - rest_[c.node];
      for (int i = 0; i < 3; ++i) rows_.push_back({c.node, Eigen::Vector3d::Unit(i), target[i]});
    }
    const ExactFemStepStats s = solve_rows(Field::kWhole);
    for (const auto& c : contacts_) {
      if (!deferred_[c.node]) u_.segment<3>(3 * c.node) = c.target_mm - rest_[c.node];
    }
    update_deformed();
    out.iterations = 1;
    out.contact_nodes = s.contact_nodes;
    out.contact_force_n = s.contact_force_n;
  }
  out.inverted_tets = geometry::count_inverted_tets(tets_, deformed_);
  const double inverted_fraction = static_cast<double>(out.inverted_tets) /
                                   static_cast<double>(std::max<std::size_t>(1, tets_.size()));
  if (inverted_fraction > settings_.max_inverted_fraction || !u_.allFinite()) {
    out.diverged = true;
    out.cause = u_.allFinite() ? DivergenceCause::kInverted : DivergenceCause::kNonFinite;
    out.recovery = Recovery::kKeptLastGood;
    forget_contacts();
    u_ = last_good_u_;
    update_deformed();
  }
  return out;
}

void ExactFem::update_deformed() {
  for (int node = 0; node < node_count(); ++node) {
    deformed_[node] = rest_[node] + u_.segment<3>(3 * node);
  }
}

}  // namespace ultrasim::sim
