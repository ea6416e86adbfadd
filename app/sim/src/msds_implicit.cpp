// MsdsEngine's implicit Euler step (e); the explicit step and the frame logic are in msds.cpp.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "msds_chunks.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {

using msds_detail::chunk_count;
using msds_detail::kNodesPerChunk;
using msds_detail::kSpringsPerChunk;

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
// nodes have v1 = 0 and drop out of the system. Jacobi-preconditioned CG, matrix-free: each node
// gathers h C_s + h² K_s (p_i − p_j) over its springs.
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

void MsdsEngine::compute_spring_forces(double dt_s) {
  // Each spring once (its length and direction cost a square root and a division); the node
  // passes then sum their springs' forces (sum_node_forces): no two tasks write the same place,
  // and every node adds in the same order with or without jobs.
  const int spring_count = static_cast<int>(springs_.size());
  for_each_chunk(chunk_count(spring_count, kSpringsPerChunk), [&](int chunk) {
    const int end = std::min(spring_count, (chunk + 1) * kSpringsPerChunk);
    for (int s = chunk * kSpringsPerChunk; s < end; ++s) {
      const MsdsSpring& spring = springs_[s];
      double length = 0.0;
      const Eigen::Vector3d dir =
          spring_direction(spring.a, spring.b, spring.rest_length_mm, length);
      // Force on node a; node b gets the opposite. Damping along the spring only (the relative
      // velocity projected on its direction): it resists stretching and compression but not a
      // rigid rotation of the edge, as in the published MSDS.
      spring_force_along_[s] = {
          spring.stiffness_mn_per_mm * (length - spring.rest_length_mm),
          spring.damping_mn_s_per_mm * (velocity_[spring.b] - velocity_[spring.a]).dot(dir)};
      spring_block_[s] = implicit_spring_block(spring, dir, length, dt_s);
    }
  });
}

void MsdsEngine::sum_node_forces(int node, Eigen::Vector3d& elastic_mn, Eigen::Vector3d& damping_mn,
                                 Eigen::Vector3d& block_diagonal) const {
  elastic_mn.setZero();
  damping_mn.setZero();
  block_diagonal.setZero();
  for (int e = adjacency_begin_[node]; e < adjacency_begin_[node + 1]; ++e) {
    const int s = adjacency_spring_[e];
    const ImplicitSpringBlock& block = spring_block_[s];
    const double sign = adjacency_sign_[e];
    elastic_mn += (sign * spring_force_along_[s].elastic_mn) * block.dir;
    damping_mn += (sign * spring_force_along_[s].damping_mn) * block.dir;
    block_diagonal += block.diagonal();
  }
}

MsdsEngine::StepResult MsdsEngine::implicit_euler_update(double dt_s) {
  const int n = node_count();
  const int chunks = node_chunk_count();
  // The CG starts at v0 (the warm start) or, after a step the budget stopped, at that step's
  // unfinished velocity; either is zero on every contact (held or released) and pinned node, so
  // a neighbour's release in the pass below does not change what a node reads.
  const bool kept_start = truncated_velocity_kept_;
  for_each_chunk(chunks, [&](int chunk) {
    bool moving = false;
    const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
    for (int i = chunk * kNodesPerChunk; i < end; ++i) {
      if (!kept_start || !moves(i)) cg_velocity_[i] = velocity_[i];
      moving = moving || !(cg_velocity_[i].array() == 0.0).all();  // NaN counts as moving
    }
    partial_a_[chunk] = moving ? 1.0 : 0.0;
  });
  // From a zero start, A v0 = 0 and the start's residual is the right-hand side: the product is
  // skipped (it was an eighth of a starved sub-volume's frame).
  const bool from_zero = sum_partials(partial_a_, chunks) == 0.0;
  // A kept start is tested below against a zero one.
  const bool test_kept_start = kept_start && !from_zero;
  // One pass per node: its forces, the contact release, its row of the system and the start's
  // residual; for a kept start, what a zero start would have (r = rhs) and the step's energy at
  // the start, E(v) = ½ vᵀA v − rhsᵀv = −½ vᵀ(rhs + r).
  for_each_chunk(chunks, [&](int chunk) {
    double rhs_squared = 0.0, rz = 0.0, rr = 0.0, rz_zero = 0.0, energy = 0.0;
    const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
    for (int i = chunk * kNodesPerChunk; i < end; ++i) {
      if (!pinned_[i]) {
        Eigen::Vector3d elastic, damping, block_diagonal;
        sum_node_forces(i, elastic, damping, block_diagonal);
        Eigen::Vector3d anchor_elastic, anchor_damping;
        anchor_force(i, anchor_elastic, anchor_damping);
        elastic += anchor_elastic;
        release_if_pulled_away(i, elastic + damping + anchor_damping);
        if (!held_[i]) {
          const Eigen::Vector3d diagonal =
              Eigen::Vector3d::Constant(mass_kg_[i] + anchor_system_diagonal(i, dt_s)) +
              block_diagonal;
          inverse_diagonal_[i] = diagonal.cwiseInverse();
          rhs_[i] = mass_kg_[i] * velocity_[i] + dt_s * elastic;
          r_[i] = from_zero ? rhs_[i]
                            : Eigen::Vector3d(rhs_[i] - system_row_times(i, cg_velocity_, dt_s));
          z_[i] = inverse_diagonal_[i].cwiseProduct(r_[i]);
          p_[i] = z_[i];
          rhs_squared += rhs_[i].squaredNorm();
          rz += r_[i].dot(z_[i]);
          rr += r_[i].squaredNorm();
          if (test_kept_start) {
            rz_zero += rhs_[i].dot(inverse_diagonal_[i].cwiseProduct(rhs_[i]));
            energy -= 0.5 * cg_velocity_[i].dot(rhs_[i] + r_[i]);
          }
          continue;
        }
      }
      // Not in the system: zero rows keep r, z, p (and so v's update) zero here.
      inverse_diagonal_[i].setZero();
      rhs_[i].setZero();
      r_[i].setZero();
      z_[i].setZero();
      p_[i].setZero();
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
        cg_velocity_[i].setZero();
        r_[i] = rhs_[i];
        z_[i] = inverse_diagonal_[i].cwiseProduct(r_[i]);
        p_[i] = z_[i];
      }
    });
    rz = sum_partials(partial_d_, chunks);
    residual = reference;
  }
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
    for_each_chunk(chunks, [&](int chunk) {
      double pq = 0.0;
      const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
      for (int i = chunk * kNodesPerChunk; i < end; ++i) {
        q_[i] = moves(i) ? system_row_times(i, p_, dt_s) : Eigen::Vector3d::Zero();
        pq += p_[i].dot(q_[i]);
      }
      partial_a_[chunk] = pq;
    });
    const double pq = sum_partials(partial_a_, chunks);
    if (!(pq > 0.0)) break;  // converged to rounding (the system is positive definite)
    const double alpha = rz / pq;
    for_each_chunk(chunks, [&](int chunk) {
      double rz_chunk = 0.0, rr = 0.0;
      const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
      for (int i = chunk * kNodesPerChunk; i < end; ++i) {
        cg_velocity_[i] += alpha * p_[i];
        r_[i] -= alpha * q_[i];
        z_[i] = inverse_diagonal_[i].cwiseProduct(r_[i]);
        rz_chunk += r_[i].dot(z_[i]);
        rr += r_[i].squaredNorm();
      }
      partial_a_[chunk] = rz_chunk;
      partial_b_[chunk] = rr;
    });
    const double rz_next = sum_partials(partial_a_, chunks);
    const double beta = rz_next / rz;
    rz = rz_next;
    residual = std::sqrt(sum_partials(partial_b_, chunks));
    for_each_chunk(chunks, [&](int chunk) {
      const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
      for (int i = chunk * kNodesPerChunk; i < end; ++i) p_[i] = z_[i] + beta * p_[i];
    });
    ++iteration;
  }
  StepResult result = finish_implicit_update(dt_s, truncated);
  truncated_velocity_kept_ = truncated && settings_.continue_stopped_steps;
  result.cg_iterations = iteration;
  result.cg_relative_residual = reference > 0.0 ? residual / reference : 0.0;
  return result;
}

MsdsEngine::ImplicitSpringBlock MsdsEngine::implicit_spring_block(const MsdsSpring& spring,
                                                                  const Eigen::Vector3d& dir,
                                                                  double length_mm, double h) {
  // h c n nᵀ + h² k [n nᵀ + t (I − n nᵀ)] = (h c + h² k (1 − t)) n nᵀ + h² k t I.
  const double transverse = std::max(0.0, 1.0 - spring.rest_length_mm / length_mm);
  const double k = h * h * spring.stiffness_mn_per_mm;
  return {h * spring.damping_mn_s_per_mm + k * (1.0 - transverse), k * transverse, dir};
}

double MsdsEngine::anchor_system_diagonal(int node, double h) const {
  // Undamped (anchor_force says why): h² k only.
  return h * h * anchor_stiffness_mn_per_mm_[node];
}

Eigen::Vector3d MsdsEngine::system_row_times(int node, const std::vector<Eigen::Vector3d>& p,
                                             double h) const {
  // (M + h C + h² K) p at a node that moves; p is zero on nodes that do not. The anchor's row is
  // h² k I (undamped; its target is fixed within the step).
  Eigen::Vector3d sum = (mass_kg_[node] + anchor_system_diagonal(node, h)) * p[node];
  for (int e = adjacency_begin_[node]; e < adjacency_begin_[node + 1]; ++e) {
    sum += spring_block_[adjacency_spring_[e]].times(p[node] - p[adjacency_other_[e]]);
  }
  return sum;
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
      const Eigen::Vector3d& v = cg_velocity_[i];
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
