#include "ultrasim/sim/hyperelastic_fem.hpp"

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "model_checks.hpp"

namespace ultrasim::sim {

namespace {

constexpr int kTetsPerChunk = 512;
// Line search: step halvings before giving up on a Newton direction (2⁻³⁰ of a step is nothing).
constexpr int kMaxHalvings = 30;
// Armijo's sufficient decrease: the energy must fall by this fraction of the linear prediction.
constexpr double kArmijo = 1e-4;
// A held node is at its target when within this distance (mm).
constexpr double kTargetReachedMm = 1e-9;
// Contact rounds (multiplier updates) solve to this fraction of the largest force; only the last
// solve, with the final multipliers, is solved to the settings' tolerance.
constexpr double kRoundRelativeTolerance = 1e-3;
// The contact penalty per node: this many times the node's own stiffness at rest. Stiffer
// penalties leave less penetration per round; the multipliers remove the rest.
constexpr double kPenaltyPerNodeStiffness = 100.0;

using Tangent = Eigen::Matrix<double, 12, 12>;
using Vector12 = Eigen::Matrix<double, 12, 1>;

void check_settings(const HyperelasticSettings& s) {
  if (s.newton_iterations_per_frame < 1 || s.max_contact_rounds < 1 ||
      !(s.relative_force_tolerance > 0.0) || !(s.step_tolerance_mm > 0.0) ||
      !(s.contact_tolerance_mm > 0.0) || !std::isfinite(s.contact_tolerance_mm) ||
      !std::isfinite(s.relative_force_tolerance) || !std::isfinite(s.step_tolerance_mm)) {
    throw std::invalid_argument(
        "hyperelastic FEM: newton_iterations_per_frame and max_contact_rounds must be >= 1 and "
        "the tolerances positive and finite");
  }
}

Eigen::Matrix3d edge_matrix(std::span<const Eigen::Vector3d> x, const std::array<int, 4>& t) {
  Eigen::Matrix3d d;
  d.col(0) = x[t[1]] - x[t[0]];
  d.col(1) = x[t[2]] - x[t[0]];
  d.col(2) = x[t[3]] - x[t[0]];
  return d;
}

std::array<int, 4> corners(const std::array<std::int32_t, 4>& t) {
  return {t[0], t[1], t[2], t[3]};
}

// The nearest positive semi-definite matrix (eigenvalues below zero set to zero). Most tets are
// mildly strained and their tangent already positive definite: a Cholesky attempt (~20× cheaper
// than the eigensolver) settles those.
Eigen::Matrix<double, 9, 9> clamp_to_psd(const Eigen::Matrix<double, 9, 9>& h) {
  if (Eigen::LLT<Eigen::Matrix<double, 9, 9>>(h).info() == Eigen::Success) return h;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(h);
  if (eig.eigenvalues().minCoeff() >= 0.0) return h;
  const Eigen::Matrix<double, 9, 1> clamped = eig.eigenvalues().cwiseMax(0.0);
  return eig.eigenvectors() * clamped.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

struct HyperelasticFem::Factor {
  Eigen::SparseMatrix<double> tangent;  // upper triangle, column-major
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Upper> llt;
};

HyperelasticFem::HyperelasticFem(const geometry::TetMesh& mesh,
                                 std::span<const Material> tet_materials,
                                 std::span<const std::uint8_t> fixed_nodes,
                                 const HyperelasticSettings& settings, hal::JobSystem* jobs)
    : settings_(settings), jobs_(jobs), factor_(std::make_unique<Factor>()) {
  check_tet_model("hyperelastic FEM", mesh, tet_materials, fixed_nodes);
  check_settings(settings);
  for (const auto& m : tet_materials) {
    if (!(m.stiffening >= 0.0) || !std::isfinite(m.stiffening)) {
      throw std::invalid_argument("hyperelastic FEM: material '" + m.name +
                                  "': stiffening must be finite and >= 0");
    }
  }
  rest_ = mesh.rest_positions_mm;
  tets_ = mesh.tets;
  fixed_.assign(fixed_nodes.begin(), fixed_nodes.end());
  const int n = node_count();
  laws_.reserve(tets_.size());
  node_tets_.resize(n);
  for (int t = 0; t < tet_count(); ++t) {
    laws_.push_back(HyperelasticLaw::of(tet_materials[t]));
    const Eigen::Matrix3d dm = edge_matrix(rest_, corners(tets_[t]));
    rest_shape_inverse_.push_back(dm.inverse());
    rest_volume_.push_back(dm.determinant() / 6.0);
    for (int c = 0; c < 4; ++c)
      node_tets_[tets_[t][c]].emplace_back(t, static_cast<std::int8_t>(c));
  }
  x_ = rest_;
  last_good_ = rest_;
  u_ = Eigen::VectorXd::Zero(3 * n);
  held_.assign(n, 0);
  target_ = rest_;
  prescribed_.assign(n, 0);
  prescribed_displacement_.assign(n, Eigen::Vector3d::Zero());
  contact_multiplier_mn_.assign(n, 0.0);
  contact_stiffness_.assign(n, 0.0);
  load_ = Eigen::VectorXd::Zero(3 * n);
  gradient_ = rhs_ = step_ = Eigen::VectorXd::Zero(3 * n);
  tet_force_.resize(tets_.size());
  tet_tangent_.resize(tets_.size());
  chunk_partials_.resize((tets_.size() + kTetsPerChunk - 1) / kTetsPerChunk);
  build_pattern();
  // The contact penalty from each node's stiffness at rest.
  assemble(true);
  for (int node = 0; node < n; ++node) {
    double diagonal = 0.0;
    for (int i = 0; i < 3; ++i)
      diagonal += factor_->tangent.valuePtr()[diagonal_entry_[3 * node + i]];
    contact_stiffness_[node] = kPenaltyPerNodeStiffness * diagonal / 3.0;
  }
}

HyperelasticFem::~HyperelasticFem() = default;

void HyperelasticFem::build_pattern() {
  const int dofs = 3 * node_count();
  std::vector<std::vector<int>> rows_of_column(dofs);
  for (const auto& t : tets_) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        for (int i = 0; i < 3; ++i) {
          for (int k = 0; k < 3; ++k) {
            const int r = 3 * t[a] + i, c = 3 * t[b] + k;
            if (r <= c) rows_of_column[c].push_back(r);
          }
        }
      }
    }
  }
  std::vector<Eigen::Triplet<double>> entries;
  for (int c = 0; c < dofs; ++c) {
    auto& rows = rows_of_column[c];
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    for (int r : rows) entries.emplace_back(r, c, 1.0);
  }
  auto& k = factor_->tangent;
  k.resize(dofs, dofs);
  k.setFromTriplets(entries.begin(), entries.end());
  k.makeCompressed();
  const auto* outer = k.outerIndexPtr();
  const auto* inner = k.innerIndexPtr();
  auto entry = [&](int r, int c) {
    const auto* begin = inner + outer[c];
    const auto* end = inner + outer[c + 1];
    return static_cast<std::int32_t>(std::lower_bound(begin, end, r) - inner);
  };
  tet_scatter_.assign(tets_.size() * 144, -1);
  for (int t = 0; t < tet_count(); ++t) {
    for (int p = 0; p < 12; ++p) {
      for (int q = 0; q < 12; ++q) {
        const int r = 3 * tets_[t][p / 3] + p % 3, c = 3 * tets_[t][q / 3] + q % 3;
        if (r <= c) tet_scatter_[144 * t + 12 * p + q] = entry(r, c);
      }
    }
  }
  dof_entries_.assign(dofs, {});
  diagonal_entry_.assign(dofs, 0);
  for (int c = 0; c < dofs; ++c) {
    for (int e = outer[c]; e < outer[c + 1]; ++e) {
      const int r = inner[e];
      if (r == c) {
        diagonal_entry_[c] = e;
      } else {
        dof_entries_[c].emplace_back(e, r);
        dof_entries_[r].emplace_back(e, c);
      }
    }
  }
  factor_->llt.analyzePattern(k);
}

template <typename Body>
void HyperelasticFem::for_each_chunk(int count, Body&& body) const {
  hal::parallel_for(jobs_, count, [&body](int chunk) { body(chunk); });
}

void HyperelasticFem::assemble(bool with_tangent) {
  const int tets = tet_count();
  const int chunks = static_cast<int>(chunk_partials_.size());
  for_each_chunk(chunks, [&](int chunk) {
    const int end = std::min(tets, (chunk + 1) * kTetsPerChunk);
    for (int t = chunk * kTetsPerChunk; t < end; ++t) {
      const Eigen::Matrix3d& bm = rest_shape_inverse_[t];
      const Eigen::Matrix3d f = edge_matrix(x_, corners(tets_[t])) * bm;
      // ∂F_ij/∂x_(a,i) = g_a(j): g_1..3 the rows of Dm⁻¹, g_0 minus their sum.
      Eigen::Matrix<double, 3, 4> g;
      g.rightCols<3>() = bm.transpose();
      g.col(0) = -g.rightCols<3>().rowwise().sum();
      const Eigen::Matrix3d p = laws_[t].first_piola_kpa(f);
      const double v = rest_volume_[t];
      for (int a = 0; a < 4; ++a) tet_force_[t].segment<3>(3 * a) = v * p * g.col(a);
      if (!with_tangent) continue;
      Eigen::Matrix<double, 9, 12> d = Eigen::Matrix<double, 9, 12>::Zero();
      for (int a = 0; a < 4; ++a) {
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) d(i + 3 * j, 3 * a + i) = g(j, a);
        }
      }
      tet_tangent_[t].noalias() =
          v * d.transpose() * clamp_to_psd(laws_[t].stress_derivative_kpa(f)) * d;
    }
  });
  for (int node = 0; node < node_count(); ++node) {
    Eigen::Vector3d sum = -load_.segment<3>(3 * node);
    for (const auto& [t, c] : node_tets_[node]) sum += tet_force_[t].segment<3>(3 * c);
    gradient_.segment<3>(3 * node) = sum;
  }
  if (with_tangent) {
    double* values = factor_->tangent.valuePtr();
    std::fill(values, values + factor_->tangent.nonZeros(), 0.0);
    scatter_tangents();
  }
  add_contact_terms(with_tangent);
}

void HyperelasticFem::add_contact_terms(bool with_tangent) {
  if (probe_ == nullptr) return;
  double* values = factor_->tangent.valuePtr();
  const auto* outer = factor_->tangent.outerIndexPtr();
  const auto* inner = factor_->tangent.innerIndexPtr();
  for (int node = 0; node < node_count(); ++node) {
    if (held_[node]) continue;
    const double push = contact_push_mn(node, x_[node]);
    if (push <= 0.0) continue;
    const Eigen::Vector3d normal = probe_->closest_surface_point(x_[node]).normal;
    // ∂ψ/∂x = −push · n; its Gauss–Newton Hessian k n nᵀ (the surface's curvature left out).
    gradient_.segment<3>(3 * node) -= push * normal;
    if (!with_tangent) continue;
    const Eigen::Matrix3d block = contact_stiffness_[node] * normal * normal.transpose();
    for (int k = 0; k < 3; ++k) {
      const int column = 3 * node + k;
      for (int e = outer[column]; e < outer[column + 1]; ++e) {
        const int row = inner[e];
        if (row >= 3 * node && row <= column) values[e] += block(row - 3 * node, k);
      }
    }
  }
}

double HyperelasticFem::contact_push_mn(int node, const Eigen::Vector3d& x) const {
  return contact_multiplier_mn_[node] - contact_stiffness_[node] * probe_->signed_distance_mm(x);
}

double HyperelasticFem::contact_energy_uj(int node, const Eigen::Vector3d& x) const {
  // ψ = (max(0, λ − k d)² − λ²) / 2k: the augmented Lagrangian of d ≥ 0 (d: distance outside).
  const double push = std::max(0.0, contact_push_mn(node, x));
  const double lambda = contact_multiplier_mn_[node];
  return (push * push - lambda * lambda) / (2.0 * contact_stiffness_[node]);
}

void HyperelasticFem::scatter_tangents() {
  double* values = factor_->tangent.valuePtr();
  const int tets = tet_count();
  for (int t = 0; t < tets; ++t) {
    const std::int32_t* scatter = &tet_scatter_[144 * static_cast<std::size_t>(t)];
    const Tangent& k = tet_tangent_[t];
    for (int q = 0; q < 12; ++q) {
      for (int p = 0; p < 12; ++p) {
        const std::int32_t e = scatter[12 * p + q];
        if (e >= 0) values[e] += k(p, q);
      }
    }
  }
}

bool HyperelasticFem::all_tets_positive_along(double alpha) {
  const int tets = tet_count();
  const int chunks = static_cast<int>(chunk_partials_.size());
  for_each_chunk(chunks, [&](int chunk) {
    const int end = std::min(tets, (chunk + 1) * kTetsPerChunk);
    double inverted = 0.0;
    for (int t = chunk * kTetsPerChunk; t < end; ++t) {
      std::array<Eigen::Vector3d, 4> y;
      for (int c = 0; c < 4; ++c) y[c] = position_along(tets_[t][c], alpha);
      if (!(geometry::signed_tet_volume(y[0], y[1], y[2], y[3]) > 0.0)) inverted += 1.0;
    }
    chunk_partials_[chunk] = inverted;
  });
  for (double b : chunk_partials_) {
    if (b > 0.0) return false;
  }
  return true;
}

double HyperelasticFem::energy_along(double alpha) {
  const int tets = tet_count();
  const int chunks = static_cast<int>(chunk_partials_.size());
  for_each_chunk(chunks, [&](int chunk) {
    const int end = std::min(tets, (chunk + 1) * kTetsPerChunk);
    double sum = 0.0;
    for (int t = chunk * kTetsPerChunk; t < end; ++t) sum += tet_energy_uj(t, alpha);
    chunk_partials_[chunk] = sum;
  });
  double energy = 0.0;
  for (double p : chunk_partials_) energy += p;
  for (int node = 0; node < node_count(); ++node) {
    const Eigen::Vector3d x = position_along(node, alpha);
    energy -= load_.segment<3>(3 * node).dot(x - rest_[node]);
    if (probe_ != nullptr && !held_[node]) energy += contact_energy_uj(node, x);
  }
  return energy;
}

Eigen::Vector3d HyperelasticFem::position_along(int node, double alpha) const {
  return x_[node] + alpha * step_.segment<3>(3 * node);
}

double HyperelasticFem::tet_energy_uj(int t, double alpha) const {
  const auto& tet = tets_[t];
  const Eigen::Vector3d y0 = position_along(tet[0], alpha);
  Eigen::Matrix3d ds;
  for (int c = 1; c < 4; ++c) ds.col(c - 1) = position_along(tet[c], alpha) - y0;
  return rest_volume_[t] * laws_[t].energy_density_kpa(ds * rest_shape_inverse_[t]);
}

bool HyperelasticFem::newton(int max_iterations, double relative_tolerance) {
  auto& k = factor_->tangent;
  double* values = k.valuePtr();
  double first_free_force = 0.0;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    assemble(true);
    // Remaining moves of the held nodes, and the balance of the free ones.
    double remaining = 0.0, free_force = 0.0, held_force = 0.0;
    for (int node = 0; node < node_count(); ++node) {
      if (held_[node]) {
        remaining = std::max(remaining, (target_[node] - x_[node]).norm());
        held_force = std::max(held_force, gradient_.segment<3>(3 * node).norm());
      } else {
        free_force = std::max(free_force, gradient_.segment<3>(3 * node).norm());
      }
    }
    // With the probe lifted and no load the answer is rest, where every force vanishes: measure
    // the balance against the imbalance this solve started from too, or the tolerance shrinks
    // with the forces and only rounding decides when the line search gives up.
    if (iteration == 0) first_free_force = free_force;
    const double force_scale = std::max(
        {held_force, max_push_mn(), load_.lpNorm<Eigen::Infinity>(), first_free_force, 1e-12});
    last_.max_free_force_mn = free_force;
    last_.max_held_force_mn = held_force;
    const bool targets_reached = remaining <= kTargetReachedMm;
    if (targets_reached && free_force <= relative_tolerance * force_scale) {
      return true;
    }
    // Newton's system, the held DOFs eliminated symmetrically: their rows and columns become the
    // identity (scaled by their diagonal) and their moves go to the right-hand side.
    rhs_ = -gradient_;
    for (int node = 0; node < node_count(); ++node) {
      if (!held_[node]) continue;
      const Eigen::Vector3d move = target_[node] - x_[node];
      for (int i = 0; i < 3; ++i) {
        const int dof = 3 * node + i;
        for (const auto& [e, other] : dof_entries_[dof]) {
          rhs_[other] -= values[e] * move[i];
          values[e] = 0.0;
        }
      }
    }
    for (int node = 0; node < node_count(); ++node) {
      if (!held_[node]) continue;
      for (int i = 0; i < 3; ++i) {
        const int dof = 3 * node + i;
        double& diagonal = values[diagonal_entry_[dof]];
        if (!(diagonal > 0.0)) diagonal = 1.0;
        rhs_[dof] = diagonal * (target_[node][i] - x_[node][i]);
      }
    }
    factor_->llt.factorize(k);
    if (factor_->llt.info() != Eigen::Success) return false;
    step_ = factor_->llt.solve(rhs_);
    if (!step_.allFinite()) return false;

    double alpha = 1.0;
    int halvings = 0;
    while (!all_tets_positive_along(alpha) && halvings < kMaxHalvings) {
      alpha *= 0.5;
      ++halvings;
    }
    if (targets_reached) {
      // Every held node in place: the free nodes go downhill on the energy.
      const double e0 = energy_along(0.0);
      const double slope = gradient_.dot(step_);
      while (energy_along(alpha) > e0 + kArmijo * alpha * slope && halvings < kMaxHalvings) {
        alpha *= 0.5;
        ++halvings;
      }
    }
    if (halvings >= kMaxHalvings) return false;
    last_.smallest_line_search = std::min(last_.smallest_line_search, alpha);
    ++last_.newton_iterations;
    double moved = 0.0;
    for (int node = 0; node < node_count(); ++node) {
      const Eigen::Vector3d delta = alpha * step_.segment<3>(3 * node);
      x_[node] += delta;
      moved = std::max(moved, delta.norm());
    }
    if (targets_reached && alpha == 1.0 && moved <= settings_.step_tolerance_mm) {
      assemble(false);
      return true;
    }
  }
  assemble(false);
  return false;
}

void HyperelasticFem::refresh_targets() {
  for (int node = 0; node < node_count(); ++node) {
    held_[node] = fixed_[node] || prescribed_[node];
    if (fixed_[node]) {
      target_[node] = rest_[node];
    } else if (prescribed_[node]) {
      target_[node] = rest_[node] + prescribed_displacement_[node];
    }
  }
}

double HyperelasticFem::max_push_mn() const {
  double largest = 0.0;
  if (probe_ == nullptr) return largest;
  for (int node = 0; node < node_count(); ++node) {
    if (!held_[node]) largest = std::max(largest, contact_push_mn(node, x_[node]));
  }
  return largest;
}

double HyperelasticFem::update_multipliers() {
  double deepest = 0.0;
  for (int node = 0; node < node_count(); ++node) {
    if (held_[node]) continue;
    const double d = probe_->signed_distance_mm(x_[node]);
    deepest = std::max(deepest, -d);
    contact_multiplier_mn_[node] = std::max(0.0, contact_push_mn(node, x_[node]));
  }
  return deepest;
}

EngineStepStats HyperelasticFem::step(const ProbeCollider* probe, double /*frame_dt_s*/) {
  last_ = HyperelasticSolveStats{};
  last_good_ = x_;
  probe_ = probe;
  refresh_targets();
  if (probe_ == nullptr)
    std::fill(contact_multiplier_mn_.begin(), contact_multiplier_mn_.end(), 0.0);
  // Augmented Lagrangian rounds: solve with the penalty, move each node's multiplier to its
  // contact force, until no node is more than the tolerance inside the probe. The multipliers
  // carry over from the last frame, so a probe held still converges in one round.
  if (probe_ != nullptr) {
    for (int round = 0; round < settings_.max_contact_rounds; ++round) {
      ++last_.contact_rounds;
      newton(settings_.newton_iterations_per_frame, kRoundRelativeTolerance);
      if (update_multipliers() <= settings_.contact_tolerance_mm) break;
    }
  }
  ++last_.contact_rounds;
  const bool converged =
      newton(settings_.newton_iterations_per_frame, settings_.relative_force_tolerance);
  last_.converged = converged;

  EngineStepStats stats;
  stats.iterations = last_.newton_iterations;
  bool finite = true;
  for (const auto& p : x_) finite = finite && p.allFinite();
  if (!finite) {
    x_ = last_good_;
    stats.diverged = true;
    stats.cause = DivergenceCause::kNonFinite;
    stats.recovery = Recovery::kKeptLastGood;
    assemble(false);
  }
  contact_nodes_.clear();
  Eigen::Vector3d total = Eigen::Vector3d::Zero();
  if (probe_ != nullptr) {
    for (int node = 0; node < node_count(); ++node) {
      if (held_[node]) continue;
      const double push = contact_push_mn(node, x_[node]);
      if (push <= 0.0) continue;
      contact_nodes_.push_back(node);
      total += push * probe_->closest_surface_point(x_[node]).normal;
    }
  }
  stats.contact_nodes = static_cast<int>(contact_nodes_.size());
  stats.contact_force_n = 1e-3 * total.norm();
  const double scale = std::max(last_.max_held_force_mn, max_push_mn());
  stats.relative_residual = scale > 0.0 ? last_.max_free_force_mn / scale : 0.0;
  stats.inverted_tets = geometry::count_inverted_tets(tets_, x_);
  store_displacements();
  return stats;
}

HyperelasticSolveStats HyperelasticFem::solve() {
  last_ = HyperelasticSolveStats{};
  probe_ = nullptr;
  refresh_targets();
  last_.contact_rounds = 1;
  last_.converged =
      newton(settings_.newton_iterations_per_frame, settings_.relative_force_tolerance);
  store_displacements();
  return last_;
}

void HyperelasticFem::store_displacements() {
  for (int node = 0; node < node_count(); ++node) {
    u_.segment<3>(3 * node) = x_[node] - rest_[node];
  }
}

void HyperelasticFem::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != 3 * static_cast<Eigen::Index>(node_count()) || !u_mm.allFinite()) {
    throw std::invalid_argument("hyperelastic FEM: displacements need 3 finite values per node (" +
                                std::to_string(3 * node_count()) + "), got " +
                                std::to_string(u_mm.size()));
  }
  // A linear method pressed hard leaves a few tets inside out, where this law has no energy:
  // scale the field back towards rest until none is (the probe's contacts then push again).
  for (double scale = 1.0; scale > 1e-3; scale *= 0.5) {
    for (int node = 0; node < node_count(); ++node) {
      x_[node] = fixed_[node] ? rest_[node] : rest_[node] + scale * u_mm.segment<3>(3 * node);
    }
    if (geometry::count_inverted_tets(tets_, x_) == 0) {
      store_displacements();
      return;
    }
  }
  x_ = rest_;
  store_displacements();
}

void HyperelasticFem::prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm) {
  if (node < 0 || node >= node_count()) throw std::out_of_range("hyperelastic FEM: node");
  prescribed_[node] = 1;
  prescribed_displacement_[node] = displacement_mm;
}

void HyperelasticFem::release_displacement(int node) {
  if (node < 0 || node >= node_count()) throw std::out_of_range("hyperelastic FEM: node");
  prescribed_[node] = 0;
}

void HyperelasticFem::set_nodal_load(int node, const Eigen::Vector3d& force_mn) {
  if (node < 0 || node >= node_count()) throw std::out_of_range("hyperelastic FEM: node");
  load_.segment<3>(3 * node) = force_mn;
}

Eigen::Vector3d HyperelasticFem::reaction_force_mn(int node) const {
  return gradient_.segment<3>(3 * node);
}

}  // namespace ultrasim::sim
