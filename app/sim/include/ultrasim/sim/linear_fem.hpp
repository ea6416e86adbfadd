#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/node_block_matrix.hpp"
#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/settings.hpp"
#include "ultrasim/sim/sliding_nodes.hpp"
#include "ultrasim/sim/sphere_collider.hpp"

namespace ultrasim::sim {

// What one simulation step did, for the stats overlay and the report.
struct FemStepStats {
  int pcg_iterations = 0;
  double relative_residual = 0.0;  // free-DOF residual over max(|rhs|, frame's first residual)
  int contact_nodes = 0;
  double contact_force_n = 0.0;  // magnitude of the total force on the contact nodes, newtons
  bool reset_after_divergence = false;
  bool cut_short = false;  // the step's budget stopped CG before pcg_iterations_per_frame
};

// Quasi-static linear FEM as published: isotropic linear elasticity, Cauchy (small) strain,
// linear tetrahedra, solved by Jacobi-preconditioned conjugate gradients with a fixed iteration
// budget per frame, warm-started from the previous frame. Fixed nodes and the nodes the probe
// holds are Dirichlet constraints; CG runs on the free degrees of freedom only. Under the default
// Coulomb slip contact (HeldContactSettings) a held node that slides is held along the probe's
// normal only and slides in the tangent plane inside the CG (a filtered CG, as the exact FEM's
// tangent-plane rows), so a still probe's patch settles with the rest of the tissue.
//
// Units: positions mm, moduli kPa, so K u is in mN. With a job system, each CG product runs in
// row bands on its threads (the rest of a step on the caller); step() does not allocate.
// As a DeformationEngine (the kiosk's method (a)): probe contact by any ProbeCollider shape, and a
// press so deep that more than max_inverted_fraction of the tets invert keeps the last good shape
// (a shape that starts over the limit, folded by another engine, may end a frame with up to as
// many, not more: else every frame would be refused and keep them while the CG could unfold
// them).
class LinearFem final : public DeformationEngine {
 public:
  // tet_materials: one material per tet; fixed_nodes: one flag per node (nonzero = fixed).
  // Throws std::invalid_argument when no node is fixed (the stiffness would be singular), a tet
  // has no positive volume, or a material is out of its physical range. Allocates.
  // `jobs`, if given, must outlive the engine; none when it is itself one task of a job system's
  // (a stitched sub-volume: tasks must not run jobs).
  LinearFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
            std::span<const std::uint8_t> fixed_nodes, const FemSettings& settings,
            hal::JobSystem* jobs = nullptr);

  // Holds node `node` at the given displacement (mm) until released; fixed nodes stay at zero.
  // Does not allocate.
  void prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm);
  void release_displacement(int node);

  // Collides the probe with the current shape, then runs up to pcg_iterations_per_frame.
  FemStepStats step(const SphereCollider& collider);

  // Step with nothing touching the tissue (probe lifted): tissue relaxes toward rest.
  FemStepStats step_without_contact();

  // DeformationEngine (frame_dt_s is ignored: quasi-static).
  EngineKind kind() const override { return EngineKind::kPcgFem; }
  std::string_view name() const override { return "PCG FEM (published)"; }
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  // Fewer CG iterations when the budget runs out (one at least).
  EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                              const StepBudget& may_continue) override;
  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  // Warm start from this shape; the probe's contacts are found afresh at the next step.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  // Anchor springs: their stiffness joins K's diagonal and their pull the right-hand side.
  bool supports_anchor_springs() const override { return true; }
  void set_anchor_springs(std::span<const AnchorSpring> anchors) override;

  // Coarse correction of a stitched volume: K; −K u; fixed, prescribed or in contact; u += du on
  // the free nodes and its tangential part on the sliding ones (the next step warm-starts from it
  // and finds the contacts as usual).
  Eigen::SparseMatrix<double, Eigen::RowMajor> rest_stiffness_mn_per_mm() const override {
    return stiffness_;
  }
  void tissue_forces_mn(Eigen::VectorXd& forces_mn) const override;
  bool holds_node(int node) const override {
    return fixed_[node] != 0 || prescribed_[node] != 0 || in_contact_[node] != 0;
  }
  const SlidingHold* sliding_hold(int node) const override { return sliding_.hold(node); }
  void displace_free_nodes_mm(const Eigen::VectorXd& du_mm) override;
  void move_held_node_mm(int node, const Eigen::Vector3d& position_mm) override;

  // Nodal forces K u (− the anchor's pull) on node n, mN: the reaction where the node is
  // constrained (a sliding node's along the probe's normal, plus its friction), ~0 where free.
  Eigen::Vector3d nodal_force_mn(int node) const;

  // Deformed node positions (rest + displacement), mm; valid until the next step.
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return deformed_; }
  // Displacement of node n, mm.
  Eigen::Vector3d displacement_mm(int node) const { return u_.segment<3>(3 * node); }

  // Runs CG on the current constraints (fixed, prescribed, and last step's contacts) until the
  // relative residual is below `tolerance` (or max_iterations). For tests and accuracy reports: the
  // converged answer of this frame's problem.
  FemStepStats solve_to_tolerance(double tolerance, int max_iterations);

  const Eigen::SparseMatrix<double, Eigen::RowMajor>& stiffness() const { return stiffness_; }
  int node_count() const { return static_cast<int>(rest_.size()); }
  int fixed_node_count() const { return fixed_count_; }

 private:
  FemStepStats step_probe(const ProbeCollider* probe, const StepBudget& may_continue);
  void apply_collider(const ProbeCollider* collider);
  // free_mask_ from the fixed, prescribed, contact and sliding nodes as they are.
  void mask_held_nodes();
  // S: zeroes what the constraints hold in `v` (per node: all of a fixed, prescribed or stuck
  // node; the probe's normal component of a sliding one). Does not allocate.
  void constrain(Eigen::VectorXd& v) const;
  // forces_mn += the loads: the anchor springs' pull and the friction on sliding nodes.
  void add_loads(Eigen::VectorXd& forces_mn) const;
  FemStepStats run_pcg(int max_iterations, double tolerance, const StepBudget& may_continue);
  // Stores each contact node's push along the probe's outward normal; returns |total| in N.
  double update_contact_forces();
  // out = (K + A) p, A the anchor springs' diagonal stiffness; in row bands on the job system,
  // the same to the last bit on any number of threads. out must have K's rows.
  void system_times(const Eigen::VectorXd& p, Eigen::VectorXd& out) const;
  void update_deformed();

  FemSettings settings_;
  hal::JobSystem* jobs_ = nullptr;
  std::vector<Eigen::Vector3d> rest_;
  std::vector<std::uint8_t> fixed_;
  std::vector<std::uint8_t> prescribed_;
  std::vector<std::uint8_t> in_contact_;
  std::vector<double> contact_push_mn_;  // per node: probe's push along its outward normal
  std::vector<std::uint8_t> only_held_by_adhesion_;  // touching, not inside: may be let go
  std::vector<Eigen::Vector3d> u_before_contact_;    // where a let-go node returns to
  std::vector<Eigen::Vector3d> contact_normal_;      // probe's outward normal at each contact
  // HeldContactModel::kCoulombSlip: the held nodes that slide this frame, held along the probe's
  // normal only, inside the CG (coulomb_hold()).
  SlidingNodes sliding_;
  std::vector<std::array<std::int32_t, 4>> tets_;
  Eigen::VectorXd last_good_u_;
  int fixed_count_ = 0;
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness_;
  detail::NodeBlockMatrix stiffness_blocks_;             // the same K, for the CG's products
  mutable std::vector<Eigen::VectorXd> product_spills_;  // per band of stiffness_blocks_
  Eigen::VectorXd stiffness_diagonal_;
  Eigen::VectorXd inverse_diagonal_;  // of K + A
  // Anchor springs: per DOF their stiffness (mN/mm) and k (target − rest) (mN).
  Eigen::VectorXd anchor_stiffness_, anchor_load_mn_;
  std::vector<int> anchored_nodes_;
  bool has_anchors_ = false;
  // Per-step state and scratch, sized once.
  Eigen::VectorXd u_, free_mask_, r_, z_, p_, q_;
  std::vector<Eigen::Vector3d> deformed_;
  // Whether the step's shape (u_) has more inverted tets than the limit and than the shape it
  // started from (last_good_u_), which it may keep.
  bool inverts_too_many(int inverted_tets);
};

// The global stiffness (3·nodes square, node-major x,y,z; kPa·mm, so K u is in mN) of linear tets
// with one isotropic material each. Inputs as checked by the engines' constructors. Allocates.
Eigen::SparseMatrix<double, Eigen::RowMajor> assemble_stiffness(
    const geometry::TetMesh& mesh, std::span<const Material> tet_materials);

// Element stiffness of a linear tet (12×12, node-major x,y,z) for an isotropic material.
// Exposed for tests against hand-derived values.
Eigen::Matrix<double, 12, 12> tet_stiffness(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                            const Eigen::Vector3d& p2, const Eigen::Vector3d& p3,
                                            double youngs_modulus_kpa, double poisson_ratio);

}  // namespace ultrasim::sim
