#include "ultrasim/sim/linear_fem.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "jacobi_cg.hpp"
#include "model_checks.hpp"
#include "sparse_products.hpp"
#include "ultrasim/sim/contact.hpp"

namespace ultrasim::sim {

Eigen::Matrix<double, 12, 12> tet_stiffness(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                            const Eigen::Vector3d& p2, const Eigen::Vector3d& p3,
                                            double youngs_modulus_kpa, double poisson_ratio) {
  Eigen::Matrix3d edges;
  edges << p1 - p0, p2 - p0, p3 - p0;
  const double volume = edges.determinant() / 6.0;
  // Rows of edges⁻¹ are the gradients of the shape functions of nodes 1..3.
  const Eigen::Matrix3d grads = edges.inverse();
  Eigen::Matrix<double, 4, 3> g;
  g.row(1) = grads.row(0);
  g.row(2) = grads.row(1);
  g.row(3) = grads.row(2);
  g.row(0) = -(g.row(1) + g.row(2) + g.row(3));

  // Strain-displacement matrix, Voigt order xx yy zz xy yz zx with engineering shear strains.
  Eigen::Matrix<double, 6, 12> b = Eigen::Matrix<double, 6, 12>::Zero();
  for (int a = 0; a < 4; ++a) {
    const double bx = g(a, 0), by = g(a, 1), bz = g(a, 2);
    b(0, 3 * a) = bx;
    b(1, 3 * a + 1) = by;
    b(2, 3 * a + 2) = bz;
    b(3, 3 * a) = by;
    b(3, 3 * a + 1) = bx;
    b(4, 3 * a + 1) = bz;
    b(4, 3 * a + 2) = by;
    b(5, 3 * a) = bz;
    b(5, 3 * a + 2) = bx;
  }
  const double e = youngs_modulus_kpa, nu = poisson_ratio;
  const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu));
  const double mu = e / (2 * (1 + nu));
  Eigen::Matrix<double, 6, 6> d = Eigen::Matrix<double, 6, 6>::Zero();
  d.topLeftCorner<3, 3>().setConstant(lambda);
  d.topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
  d.bottomRightCorner<3, 3>().diagonal().setConstant(mu);
  return volume * b.transpose() * d * b;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> assemble_stiffness(
    const geometry::TetMesh& mesh, std::span<const Material> tet_materials) {
  const auto& p = mesh.rest_positions_mm;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(mesh.tets.size() * 144);
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& tet = mesh.tets[t];
    const auto ke =
        tet_stiffness(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]],
                      tet_materials[t].youngs_modulus_kpa, tet_materials[t].poisson_ratio);
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            triplets.emplace_back(3 * tet[a] + i, 3 * tet[b] + j, ke(3 * a + i, 3 * b + j));
  }
  const int dofs = 3 * mesh.node_count();
  Eigen::SparseMatrix<double, Eigen::RowMajor> k(dofs, dofs);
  k.setFromTriplets(triplets.begin(), triplets.end());
  k.makeCompressed();
  return k;
}

LinearFem::LinearFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
                     std::span<const std::uint8_t> fixed_nodes, const FemSettings& settings,
                     hal::JobSystem* jobs)
    : settings_(settings),
      jobs_(jobs),
      rest_(mesh.rest_positions_mm),
      fixed_(fixed_nodes.begin(), fixed_nodes.end()),
      prescribed_(mesh.rest_positions_mm.size(), 0),
      in_contact_(mesh.rest_positions_mm.size(), 0),
      contact_push_mn_(mesh.rest_positions_mm.size(), 0.0),
      only_held_by_adhesion_(mesh.rest_positions_mm.size(), 0),
      u_before_contact_(mesh.rest_positions_mm.size(), Eigen::Vector3d::Zero()),
      contact_normal_(mesh.rest_positions_mm.size(), Eigen::Vector3d::UnitZ()),
      sliding_(mesh.node_count()),
      tets_(mesh.tets),
      deformed_(mesh.rest_positions_mm) {
  const int n = mesh.node_count();
  fixed_count_ = check_tet_model("LinearFem", mesh, tet_materials, fixed_nodes);
  if (settings.pcg_iterations_per_frame < 1) {
    throw std::invalid_argument("pcg_iterations_per_frame must be >= 1");
  }
  if (!(settings.max_inverted_fraction >= 0.0 && settings.max_inverted_fraction <= 1.0)) {
    throw std::invalid_argument("max_inverted_fraction must be in [0, 1]");
  }
  check_held_contact_settings(settings.contact, "LinearFem");
  stiffness_ = assemble_stiffness(mesh, tet_materials);
  // Two bands a thread (their costs differ where the mesh's rows are fuller), and never fewer
  // than on two threads: one thread then gives the two threads' answer to the last bit.
  stiffness_blocks_ = detail::NodeBlockMatrix(
      stiffness_, 2 * std::max(2, jobs_ != nullptr ? jobs_->thread_count() : 1));
  product_spills_.resize(stiffness_blocks_.bands());
  for (int band = 0; band < stiffness_blocks_.bands(); ++band) {
    product_spills_[band].setZero(stiffness_blocks_.spill_rows(band));
  }
  stiffness_diagonal_ = stiffness_.diagonal();
  inverse_diagonal_ = stiffness_diagonal_.cwiseInverse();
  anchor_stiffness_ = anchor_load_mn_ = Eigen::VectorXd::Zero(3 * n);

  u_ = Eigen::VectorXd::Zero(3 * n);
  free_mask_ = Eigen::VectorXd::Ones(3 * n);
  for (int node = 0; node < n; ++node) {
    if (fixed_[node]) free_mask_.segment<3>(3 * node).setZero();
  }
  r_ = z_ = p_ = q_ = Eigen::VectorXd::Zero(3 * n);
  last_good_u_ = u_;
}

void LinearFem::prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm) {
  if (fixed_[node]) return;
  prescribed_[node] = 1;
  u_.segment<3>(3 * node) = displacement_mm;
  free_mask_.segment<3>(3 * node).setZero();
}

void LinearFem::release_displacement(int node) {
  prescribed_[node] = 0;
  if (!fixed_[node] && !in_contact_[node]) free_mask_.segment<3>(3 * node).setOnes();
}

Eigen::Vector3d LinearFem::nodal_force_mn(int node) const {
  Eigen::Vector3d f;
  for (int i = 0; i < 3; ++i) f[i] = stiffness_.row(3 * node + i).dot(u_);
  if (has_anchors_) {
    f += anchor_stiffness_.segment<3>(3 * node).cwiseProduct(u_.segment<3>(3 * node)) -
         anchor_load_mn_.segment<3>(3 * node);
  }
  return f;
}

void LinearFem::tissue_forces_mn(Eigen::VectorXd& forces_mn) const {
  forces_mn.setZero();
  forces_mn.noalias() -= stiffness_ * u_;
}

void LinearFem::displace_free_nodes_mm(const Eigen::VectorXd& du_mm) {
  displace_free_and_sliding_nodes(*this, sliding_, prescribed_, du_mm, u_);
  update_deformed();
}

void LinearFem::move_held_node_mm(int node, const Eigen::Vector3d& position_mm) {
  if (fixed_[node] || !holds_node(node)) return;
  u_.segment<3>(3 * node) = position_mm - rest_[node];
  deformed_[node] = position_mm;
}

void LinearFem::set_anchor_springs(std::span<const AnchorSpring> anchors) {
  check_anchor_springs(anchors, node_count());
  for (int node : anchored_nodes_) {
    anchor_stiffness_.segment<3>(3 * node).setZero();
    anchor_load_mn_.segment<3>(3 * node).setZero();
    inverse_diagonal_.segment<3>(3 * node) =
        stiffness_diagonal_.segment<3>(3 * node).cwiseInverse();
  }
  anchored_nodes_.clear();
  for (const auto& a : anchors) {
    // k (target − x) = k (target − rest) − k u: a load and a diagonal stiffness.
    anchor_stiffness_.segment<3>(3 * a.node).setConstant(a.stiffness_mn_per_mm);
    anchor_load_mn_.segment<3>(3 * a.node) = a.stiffness_mn_per_mm * (a.target_mm - rest_[a.node]);
    inverse_diagonal_.segment<3>(3 * a.node) =
        (stiffness_diagonal_.segment<3>(3 * a.node).array() + a.stiffness_mn_per_mm).inverse();
    anchored_nodes_.push_back(a.node);
  }
  has_anchors_ = !anchored_nodes_.empty();
}

void LinearFem::system_times(const Eigen::VectorXd& p, Eigen::VectorXd& out) const {
  // The product is most of a CG iteration: the matrix's bands of node rows, on the job system's
  // threads when there is one (the same sum either way).
  const Eigen::VectorXd* anchors = has_anchors_ ? &anchor_stiffness_ : nullptr;
  hal::parallel_for(jobs_, stiffness_blocks_.bands(), [&](int band) {
    stiffness_blocks_.times_band(band, p, anchors, out, product_spills_[band]);
  });
  stiffness_blocks_.add_spills(product_spills_, out);
}

void LinearFem::apply_collider(const ProbeCollider* collider) {
  const int n = node_count();
  // Signorini contact with an active set. A node inside the probe is pushed out to its surface.
  // A node that touched last frame and was pushed on stays on the (moved) surface, so a probe
  // lifting slowly is followed by the tissue instead of dropping it all at once; but if holding
  // it there would need the probe to pull (its reaction at the new place points into the
  // probe), it is let go where it was.
  for (int node = 0; node < n; ++node) {
    const bool was_pressed = in_contact_[node] != 0 && contact_push_mn_[node] > 0.0;
    in_contact_[node] = 0;
    only_held_by_adhesion_[node] = 0;
    if (fixed_[node]) u_.segment<3>(3 * node).setZero();
    if (fixed_[node] || prescribed_[node] || collider == nullptr) continue;
    const Eigen::Vector3d p = rest_[node] + u_.segment<3>(3 * node);
    const SurfacePoint surface = collider->closest_surface_point(p);
    const bool inside = (p - surface.point_mm).dot(surface.normal) < 0.0;
    if (!inside && !was_pressed) continue;
    u_before_contact_[node] = u_.segment<3>(3 * node);
    u_.segment<3>(3 * node) = surface.point_mm - rest_[node];
    contact_normal_[node] = surface.normal;
    in_contact_[node] = 1;
    only_held_by_adhesion_[node] = !inside;
  }
  if (collider != nullptr) {
    for (int node = 0; node < n; ++node) {
      if (!only_held_by_adhesion_[node]) continue;
      contact_push_mn_[node] = nodal_force_mn(node).dot(contact_normal_[node]);
    }
    for (int node = 0; node < n; ++node) {
      if (only_held_by_adhesion_[node] && contact_push_mn_[node] <= 0.0) {
        u_.segment<3>(3 * node) = u_before_contact_[node];
        in_contact_[node] = 0;
      }
    }
  }
  sliding_.clear();
  if (collider != nullptr && settings_.contact.model == HeldContactModel::kCoulombSlip) {
    for (int node = 0; node < n; ++node) {
      if (!in_contact_[node]) continue;
      // nodal_force_mn is what holds the node where it is: the tissue's force is its opposite.
      const HeldNodeLaw law = coulomb_hold(contact_normal_[node], -nodal_force_mn(node),
                                           settings_.contact.friction_coefficient);
      if (law.slides) sliding_.add(node, contact_normal_[node], law.friction_mn);
    }
  }
  mask_held_nodes();
}

void LinearFem::mask_held_nodes() {
  for (int node = 0; node < node_count(); ++node) {
    const bool held = fixed_[node] || prescribed_[node] || in_contact_[node];
    free_mask_.segment<3>(3 * node).setConstant(held ? 0.0 : 1.0);
  }
  for (int node : sliding_.nodes()) free_mask_.segment<3>(3 * node).setOnes();
}

void LinearFem::constrain(Eigen::VectorXd& v) const {
  v.array() *= free_mask_.array();
  sliding_.project_all(v);
}

FemStepStats LinearFem::run_pcg(int max_iterations, double tolerance,
                                const StepBudget& may_continue) {
  FemStepStats stats;
  // The free system is S (K + A) S u = S b with b = f_A + f_μ − K u_c (S: constrain(), the
  // directions the nodes may move; u_c = u − S u, what the constraints hold; A, f_A: the anchor
  // springs' stiffness and load; f_μ: the friction on sliding nodes; no other external loads):
  // measure the residual against |S b|, so a warm start that is already close does not make the
  // tolerance stricter.
  q_ = u_;
  constrain(q_);
  q_ = u_ - q_;
  // A full product here was a third of a one-iteration step on the large case's sub-volumes.
  detail::symmetric_times_sparse_vector(stiffness_, has_anchors_ ? &anchor_stiffness_ : nullptr, q_,
                                        z_);
  z_ = -z_;
  add_loads(z_);
  constrain(z_);
  const double rhs_norm = z_.norm();
  system_times(u_, r_);
  r_ = -r_;
  add_loads(r_);
  constrain(r_);
  // With nothing prescribed (probe lifted) the answer is rest and |b| = 0: measure progress
  // against where this frame started instead.
  const double reference = std::max({rhs_norm, r_.norm(), 1e-30});
  z_ = inverse_diagonal_.cwiseProduct(r_);
  sliding_.project_all(z_);
  p_ = z_;
  double rz = r_.dot(z_);
  double residual = r_.norm();
  int it = 0;
  while (it < max_iterations && residual > tolerance * reference) {
    if (it > 0 && may_continue && !may_continue()) {
      stats.cut_short = true;
      break;
    }
    system_times(p_, q_);
    constrain(q_);
    // Converged to rounding or the system lost definiteness: stop.
    // r is constrained, so M⁻¹ r is zero where the mask is: only the sliding nodes need S.
    const auto filter = [this](Eigen::VectorXd& v) { sliding_.project_all(v); };
    if (!jacobi_cg_update(inverse_diagonal_, q_, u_, r_, z_, p_, rz, filter)) break;
    residual = r_.norm();
    ++it;
  }
  stats.pcg_iterations = it;
  stats.relative_residual = residual / reference;
  if (!u_.allFinite()) {
    // Never let a blown-up solve reach the screen: start again from rest.
    u_.setZero();
    stats.reset_after_divergence = true;
  }
  return stats;
}

void LinearFem::add_loads(Eigen::VectorXd& forces_mn) const {
  if (has_anchors_) forces_mn += anchor_load_mn_;
  sliding_.add_friction(forces_mn);
}

double LinearFem::update_contact_forces() {
  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (int node = 0; node < node_count(); ++node) {
    contact_push_mn_[node] = 0.0;
    if (!in_contact_[node]) continue;
    const Eigen::Vector3d force = nodal_force_mn(node);
    contact_push_mn_[node] = force.dot(contact_normal_[node]);
    total_mn += sliding_.slides(node) ? sliding_.probe_force_mn(node, force) : force;
  }
  return total_mn.norm() / 1000.0;
}

void LinearFem::update_deformed() {
  for (int node = 0; node < node_count(); ++node) {
    deformed_[node] = rest_[node] + u_.segment<3>(3 * node);
  }
}

FemStepStats LinearFem::step(const SphereCollider& collider) {
  const ProbeCollider probe = ProbeCollider::sphere(collider);
  return step_probe(&probe, {});
}

FemStepStats LinearFem::step_without_contact() {
  return step_probe(nullptr, {});
}

FemStepStats LinearFem::step_probe(const ProbeCollider* probe, const StepBudget& may_continue) {
  apply_collider(probe);
  FemStepStats stats =
      run_pcg(settings_.pcg_iterations_per_frame, settings_.relative_tolerance, may_continue);
  for (auto c : in_contact_) stats.contact_nodes += c;
  stats.contact_force_n = update_contact_forces();
  update_deformed();
  return stats;
}

EngineStepStats LinearFem::step(const ProbeCollider* probe, double frame_dt_s) {
  return step_within(probe, frame_dt_s, {});
}

EngineStepStats LinearFem::step_within(const ProbeCollider* probe, double /*frame_dt_s*/,
                                       const StepBudget& may_continue) {
  last_good_u_ = u_;
  const FemStepStats fem = step_probe(probe, may_continue);
  EngineStepStats out;
  out.cut_short = fem.cut_short;
  out.iterations = fem.pcg_iterations;
  out.relative_residual = fem.relative_residual;
  out.contact_nodes = fem.contact_nodes;
  out.contact_force_n = fem.contact_force_n;
  out.inverted_tets = geometry::count_inverted_tets(tets_, deformed_);
  if (fem.reset_after_divergence) {
    out.diverged = true;
    out.cause = DivergenceCause::kNonFinite;
    out.recovery = Recovery::kReset;
  } else if (inverts_too_many(out.inverted_tets)) {
    // Pressed through the tissue: a linear model's answer there is garbage. Show the last good.
    out.diverged = true;
    out.cause = DivergenceCause::kInverted;
    out.recovery = Recovery::kKeptLastGood;
    u_ = last_good_u_;
    std::fill(in_contact_.begin(), in_contact_.end(), 0);
    sliding_.clear();
    mask_held_nodes();
    update_deformed();
  }
  return out;
}

bool LinearFem::inverts_too_many(int inverted_tets) {
  const double limit = settings_.max_inverted_fraction * static_cast<double>(tets_.size());
  if (static_cast<double>(inverted_tets) <= limit) return false;
  // Counted only here, over the limit: the start's shape for a moment.
  u_.swap(last_good_u_);
  update_deformed();
  const int at_start = geometry::count_inverted_tets(tets_, deformed_);
  u_.swap(last_good_u_);
  update_deformed();
  return inverted_tets > at_start;
}

void LinearFem::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != u_.size()) {
    throw std::invalid_argument("LinearFem::set_displacements_mm: expected " +
                                std::to_string(u_.size()) + " values, got " +
                                std::to_string(u_mm.size()));
  }
  u_ = u_mm;
  for (int node = 0; node < node_count(); ++node) {
    if (fixed_[node]) u_.segment<3>(3 * node).setZero();
    in_contact_[node] = 0;  // the next step finds the probe's contacts afresh
  }
  sliding_.clear();
  mask_held_nodes();
  last_good_u_ = u_;
  update_deformed();
}

FemStepStats LinearFem::solve_to_tolerance(double tolerance, int max_iterations) {
  FemStepStats stats = run_pcg(max_iterations, tolerance, {});
  for (auto c : in_contact_) stats.contact_nodes += c;
  stats.contact_force_n = update_contact_forces();
  update_deformed();
  return stats;
}

}  // namespace ultrasim::sim
