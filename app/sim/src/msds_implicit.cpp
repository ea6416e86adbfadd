// MsdsEngine's implicit Euler step (e); the explicit step and the frame logic are in msds.cpp.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "msds_chunks.hpp"
#include "msds_implicit_lattice.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {

using msds_detail::kNodesPerChunk;

// A range's product fills whole node chunks' partial sums; a chunk's node sums start on a whole
// group of lanes.
static_assert(msds_detail::ImplicitLattice::kNodesPerRange % kNodesPerChunk == 0);
static_assert(kNodesPerChunk % msds_detail::kImplicitSumLanes == 0);

// Implicit Euler (e).
//
// Backward Euler: v1 = v0 + h M⁻¹ f(x0 + h v1, v1). Linearising the spring forces about x0 (one
// Newton step, Baraff & Witkin 1998), f(x0 + h v1, v1) ≈ f_e(x0) − K h v1 − C v1, where f_e is the
// elastic force, K = −∂f_e/∂x and C = −∂f/∂v (damping is linear in v). Hence
//   (M + h C + h² K) v1 = M v0 + h f_e(x0),   x1 = x0 + h v1.
// Per spring K_s = k [n nᵀ + max(0, 1 − L/l)(I − n nᵀ)]: the transverse (geometric) term is
// dropped for compressed springs, where it is negative, so the system stays symmetric positive
// definite and CG applies at any h (the usual choice, Choi & Ko 2002). C_s = c n nᵀ; the damping
// force's derivative with respect to position is neglected (Baraff & Witkin). Held and pinned
// nodes have v1 = 0 and drop out of the system. Jacobi-preconditioned CG, matrix-free: each
// spring's (h C_s + h² K_s)(p_a − p_b) once, summed ± at its two nodes (msds_implicit_lattice.hpp).
//
// A step whose CG the budget stopped keeps the move it found but not its velocity. The velocity
// is then the solve's unfinished answer, and carried on as the next step's momentum and warm
// start it fed the error back: at a stitched seam's anchors (h² k ≫ m, the other side's copy a
// step behind) the gap between two sub-volumes' copies grew several-fold a frame (the large case
// under the kiosk's budget: seams 73 mm open, 394 of 571 frames refused, 3.5 kN at the probe).
// From rest, a truncated step is a descent on the step's energy and cannot pump it; soft tissue
// is overdamped, and the next steps' solves find the velocity again. The unfinished velocity is
// kept as the next step's CG start (not its momentum) where it lowers that step's energy below a
// zero start's, so a step stopped again is still such a descent (implicit_euler_update).

namespace {

msds_detail::NodeArrays read(const std::vector<double>& x, const std::vector<double>& y,
                             const std::vector<double>& z) {
  return {x.data(), y.data(), z.data()};
}

msds_detail::MutableNodeArrays write(std::vector<double>& x, std::vector<double>& y,
                                     std::vector<double>& z) {
  return {x.data(), y.data(), z.data()};
}

}  // namespace

void MsdsEngine::compute_spring_forces(double dt_s) {
  // Each spring once, by diagonal (msds_implicit_lattice.hpp); the node pass then sums them.
  msds_detail::ImplicitLattice& lattice = *implicit_lattice_;
  const auto position = read(position_.x, position_.y, position_.z);
  for_each_chunk(lattice.range_count(),
                 [&](int range) { lattice.compute_springs(range, position, dt_s); });
}

void MsdsEngine::system_times(const NodeVectors& p, NodeVectors& q, bool pq) {
  // (M + h C + h² K) p at the nodes that move; p is zero on those that do not. The anchor's row
  // is h² k I (undamped; its target is fixed within the step).
  msds_detail::ImplicitLattice& lattice = *implicit_lattice_;
  const int n = node_count();
  for_each_chunk(lattice.range_count(), [&](int range) {
    lattice.multiply(range, system_diagonal_.data(), read(p.x, p.y, p.z), write(q.x, q.y, q.z));
    const int begin = lattice.range_begin(range);
    const int end = lattice.range_end(range);
    if (!pq) return;
    for (int chunk = begin / kNodesPerChunk; chunk * kNodesPerChunk < end; ++chunk) {
      double sum = 0.0;
      const int chunk_end = std::min(n, (chunk + 1) * kNodesPerChunk);
      for (int i = chunk * kNodesPerChunk; i < chunk_end; ++i) {
        if (!moves(i)) {
          q.x[i] = q.y[i] = q.z[i] = 0.0;
          continue;
        }
        sum += (p.x[i] * q.x[i] + p.y[i] * q.y[i]) + p.z[i] * q.z[i];
      }
      partial_a_[chunk] = sum;
    }
  });
}

MsdsEngine::StepResult MsdsEngine::implicit_euler_update(double dt_s) {
  const int n = node_count();
  const int chunks = node_chunk_count();
  // The CG starts at v0 (the warm start) or, after a step the budget stopped, at that step's
  // unfinished velocity; either is zero on every contact (held or released) and pinned node, so
  // a neighbour's release in the pass below does not change what a node reads.
  const bool kept_start = truncated_velocity_kept_;
  const double h2 = dt_s * dt_s;
  for_each_chunk(chunks, [&](int chunk) {
    bool moving = false;
    const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
    for (int i = chunk * kNodesPerChunk; i < end; ++i) {
      if (!kept_start || !moves(i)) cg_velocity_.set(i, velocity_[i]);
      // NaN counts as moving.
      moving = moving ||
               !(cg_velocity_.x[i] == 0.0 && cg_velocity_.y[i] == 0.0 && cg_velocity_.z[i] == 0.0);
      // The anchor's row is h² k I, undamped (anchor_force says why).
      system_diagonal_[i] = mass_kg_[i] + h2 * anchor_stiffness_mn_per_mm_[i];
    }
    partial_a_[chunk] = moving ? 1.0 : 0.0;
  });
  // From a zero start, A v0 = 0 and the start's residual is the right-hand side: the product is
  // skipped (it was an eighth of a starved sub-volume's frame).
  const bool from_zero = sum_partials(partial_a_, chunks) == 0.0;
  compute_spring_forces(dt_s);
  if (!from_zero) system_times(cg_velocity_, q_, false);  // A v_start, read below
  // A kept start is tested below against a zero one.
  const bool test_kept_start = kept_start && !from_zero;
  // One pass per node: its forces, the contact release, its row of the system and the start's
  // residual; for a kept start, what a zero start would have (r = rhs) and the step's energy at
  // the start, E(v) = ½ vᵀA v − rhsᵀv = −½ vᵀ(rhs + r).
  const msds_detail::ImplicitLattice& lattice = *implicit_lattice_;
  const msds_detail::StartRows rows{
      pinned_.data(),
      held_.data(),
      padded_mass_kg_.data(),
      system_diagonal_.data(),
      read(node_block_diagonal_.x, node_block_diagonal_.y, node_block_diagonal_.z),
      read(velocity_.x, velocity_.y, velocity_.z),
      read(node_elastic_.x, node_elastic_.y, node_elastic_.z),
      from_zero ? msds_detail::NodeArrays{} : read(q_.x, q_.y, q_.z),
      dt_s,
      write(inverse_diagonal_.x, inverse_diagonal_.y, inverse_diagonal_.z),
      write(rhs_.x, rhs_.y, rhs_.z),
      write(r_.x, r_.y, r_.z),
      write(z_.x, z_.y, z_.z),
      write(p_.x, p_.y, p_.z)};
  for_each_chunk(chunks, [&](int chunk) {
    const int begin = chunk * kNodesPerChunk;
    const int end = std::min(n, begin + kNodesPerChunk);
    lattice.sum_node_forces(
        begin, end, write(node_elastic_.x, node_elastic_.y, node_elastic_.z),
        write(node_block_diagonal_.x, node_block_diagonal_.y, node_block_diagonal_.z));
    for (int i = begin; i < end; ++i) {
      if (anchor_of_node_[i] >= 0) {
        Eigen::Vector3d anchor_elastic, anchor_damping;  // undamped here: see anchor_force
        anchor_force(i, anchor_elastic, anchor_damping);
        node_elastic_.set(i, node_elastic_[i] + anchor_elastic);
      }
      if (held_[i]) {
        release_if_pulled_away(
            i, node_elastic_[i] +
                   lattice.damping_force_on(i, read(velocity_.x, velocity_.y, velocity_.z)));
      }
    }
    lattice.vector_kernels().start_rows(rows, begin, end);
    double rhs_squared = 0.0, rz = 0.0, rr = 0.0, rz_zero = 0.0, energy = 0.0;
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector3d rhs = rhs_[i], r = r_[i];
      rhs_squared += rhs.squaredNorm();
      rz += r.dot(z_[i]);
      rr += r.squaredNorm();
      if (test_kept_start) {
        rz_zero += rhs.dot(inverse_diagonal_[i].cwiseProduct(rhs));
        energy -= 0.5 * cg_velocity_[i].dot(rhs + r);
      }
    }
    partial_a_[chunk] = rz;
    partial_b_[chunk] = rr;
    partial_c_[chunk] = rhs_squared;
    partial_d_[chunk] = rz_zero;
    partial_e_[chunk] = energy;
  });
  const double reference = std::sqrt(sum_partials(partial_c_, chunks));  // ‖rhs‖
  double rz = sum_partials(partial_a_, chunks);
  double residual = std::sqrt(sum_partials(partial_b_, chunks));
  // A stopped step's velocity is kept as a start only where the step's energy there is below a
  // zero start's (0): the CG lowers the energy from its start, so a step stopped again is still
  // a descent on it from rest, which cannot pump energy into the tissue (as from zero), yet goes
  // on from where the last step got to. From zero every step, a few iterations each, the smooth
  // part of a press hardly moved: under the kiosk's 4 ms share the field stayed 0.71-0.74 off
  // the unbudgeted run's while the probe slid, 0.21-0.23 going on (engine_budget_bench,
  // ImplicitMsdsShare).
  if (test_kept_start && !(sum_partials(partial_e_, chunks) < 0.0)) {
    for_each_chunk(chunks, [&](int chunk) {
      const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
      for (int i = chunk * kNodesPerChunk; i < end; ++i) {
        if (!moves(i)) continue;
        cg_velocity_.set(i, Eigen::Vector3d::Zero());
        r_.set(i, rhs_[i]);
        z_.set(i, inverse_diagonal_[i].cwiseProduct(rhs_[i]));
        p_.set(i, z_[i]);
      }
    });
    rz = sum_partials(partial_d_, chunks);
    residual = reference;
  }
  const msds_detail::CgVectors cg{
      write(cg_velocity_.x, cg_velocity_.y, cg_velocity_.z),
      write(r_.x, r_.y, r_.z),
      write(z_.x, z_.y, z_.z),
      write(p_.x, p_.y, p_.z),
      read(q_.x, q_.y, q_.z),
      read(inverse_diagonal_.x, inverse_diagonal_.y, inverse_diagonal_.z)};
  int iteration = 0;
  bool truncated = false;
  // Relative to the right-hand side, with a floor: near a static state the right-hand side is
  // itself rounding, and asking for a fraction of it would spend the whole budget every step of a
  // still probe. r / h is a force; kCgForceFloorMn of it in all is far below anything shown.
  const double target = std::max(kCgRelativeTolerance * reference, dt_s * kCgForceFloorMn);
  while (iteration < kMaxCgIterationsPerStep && residual > target) {
    // Asked on the lead thread, between the team's stages.
    if (iteration > 0 && budget_ != nullptr && !(*budget_)()) {
      cut_short_ = true;
      truncated = true;
      break;
    }
    system_times(p_, q_, true);
    const double pq = sum_partials(partial_a_, chunks);
    if (!(pq > 0.0)) break;  // converged to rounding (the system is positive definite)
    const double alpha = rz / pq;
    for_each_chunk(chunks, [&](int chunk) {
      double rz_chunk = 0.0, rr = 0.0;
      const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
      const int begin = chunk * kNodesPerChunk;
      implicit_lattice_->vector_kernels().cg_update(cg, alpha, begin, end);
      for (int i = begin; i < end; ++i) {
        rz_chunk += (r_.x[i] * z_.x[i] + r_.y[i] * z_.y[i]) + r_.z[i] * z_.z[i];
        rr += (r_.x[i] * r_.x[i] + r_.y[i] * r_.y[i]) + r_.z[i] * r_.z[i];
      }
      partial_a_[chunk] = rz_chunk;
      partial_b_[chunk] = rr;
    });
    const double rz_next = sum_partials(partial_a_, chunks);
    const double beta = rz_next / rz;
    rz = rz_next;
    residual = std::sqrt(sum_partials(partial_b_, chunks));
    for_each_chunk(chunks, [&](int chunk) {
      const int begin = chunk * kNodesPerChunk;
      const int end = std::min(n, begin + kNodesPerChunk);
      implicit_lattice_->vector_kernels().cg_direction(cg, beta, begin, end);
    });
    ++iteration;
  }
  StepResult result = finish_implicit_update(dt_s, truncated);
  truncated_velocity_kept_ = truncated && settings_.continue_stopped_steps;
  result.cg_iterations = iteration;
  result.cg_relative_residual = reference > 0.0 ? residual / reference : 0.0;
  return result;
}

MsdsEngine::StepResult MsdsEngine::finish_implicit_update(double dt_s, bool truncated) {
  const int n = node_count();
  const int chunks = node_chunk_count();
  for_each_chunk(chunks, [&](int chunk) {
    double kinetic = 0.0;
    bool finite = true;
    double min_clearance = std::numeric_limits<double>::infinity();
    const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
    for (int i = chunk * kNodesPerChunk; i < end; ++i) {
      min_clearance = std::min(min_clearance, probe_clearance_mm_[i]);
      if (!moves(i)) continue;
      const Eigen::Vector3d v = cg_velocity_[i];
      const Eigen::Vector3d x = position_[i] + dt_s * v;  // backward Euler: the new velocity
      position_.set(i, x);
      velocity_.set(i, truncated ? Eigen::Vector3d::Zero() : v);
      probe_clearance_mm_[i] -= dt_s * v.lpNorm<1>();  // see ExplicitNodeArrays
      min_clearance = std::min(min_clearance, probe_clearance_mm_[i]);
      kinetic += 0.5 * mass_kg_[i] * v.squaredNorm();
      finite = finite && x.allFinite() && v.allFinite();
    }
    partial_a_[chunk] = kinetic;
    partial_finite_[chunk] = finite;
    block_min_clearance_mm_[chunk] = min_clearance;
  });
  return gather_update_result();
}

// ---------------------------------------------------------------------------------------------
// Diagnostics.

}  // namespace ultrasim::sim
