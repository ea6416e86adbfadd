#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/hyperelastic_law.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// What the last step() or solve() did.
struct HyperelasticSolveStats {
  int newton_iterations = 0;          // over all contact rounds
  int contact_rounds = 0;             // solves: contact rounds plus the final one, ≥ 1
  bool converged = false;             // the last round met the tolerances
  double max_free_force_mn = 0.0;     // largest out-of-balance force at a free node at the end
  double max_held_force_mn = 0.0;     // largest force at a held node at the end
  double smallest_line_search = 1.0;  // smallest step fraction taken (< 1: steps were cut)
};

// Quasi-static large-strain FEM: linear tets, the hyperelastic law of HyperelasticLaw, solved by
// Newton's method. The reference for large deformation: however deep the press, no tet turns
// inside out and the force stiffens with the geometry, where the linear methods' (a)-(e) answer
// grows in proportion to the press and their tets fold under the probe's rim.
//
// Each Newton step assembles the tangent stiffness Σ Vₑ Dₑᵀ (∂P/∂F)⁺ Dₑ, each tet's ∂P/∂F
// projected to its nearest positive semi-definite matrix (Teran et al. 2005), so the step always
// goes downhill, and solves it by CHOLMOD's supernodal Cholesky (pattern analysed once). Held
// nodes (fixed, prescribed) are Dirichlet rows. A line search halves the step until every tet
// keeps a positive volume and, once every held node sits at its target, the energy falls. So a
// solution has no inverted tet by construction.
//
// Probe contact is frictionless (gel), as the exact FEM's default and Hertz's: each free node
// keeps out of the probe through an augmented Lagrangian, ψ = (max(0, λ − k d)² − λ²) / 2k with d
// its signed distance outside the probe, k a penalty (100× the node's own stiffness at rest) and
// λ its contact force, updated round by round until no node is more than contact_tolerance_mm
// inside. The probe only pushes, along its surface normal; nodes slide on it. Unlike held
// targets, a penalty can always yield, so a tet squeezed under the rim is never forced flat.
//
// A frame that does not converge within newton_iterations_per_frame keeps the shape it reached
// (every tet positive) and reports iterations; a non-finite value (never seen) restores the last
// frame (Recovery::kKeptLastGood). Units: mm, kPa, mN, µJ. With a JobSystem, the per-tet work is
// split into fixed chunks; sums are taken in chunk order, so results do not depend on the thread
// count. Allocates only at construction.
class HyperelasticFem final : public DeformationEngine {
 public:
  // Throws std::invalid_argument when no node is fixed, a tet has no positive rest volume, a
  // material is out of range (stiffening < 0 included) or a setting is.
  HyperelasticFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
                  std::span<const std::uint8_t> fixed_nodes,
                  const HyperelasticSettings& settings = {}, hal::JobSystem* jobs = nullptr);
  ~HyperelasticFem() override;
  HyperelasticFem(const HyperelasticFem&) = delete;
  HyperelasticFem& operator=(const HyperelasticFem&) = delete;

  EngineKind kind() const override { return EngineKind::kHyperelasticFem; }
  std::string_view name() const override { return "hyperelastic FEM"; }
  // stats.iterations: Newton iterations; relative_residual: largest free force / largest held.
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return x_; }
  // Throws std::invalid_argument when u_mm has the wrong size or a non-finite value, or when it
  // inverts a tet (this law has no energy there). Fixed nodes stay at rest.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  // Boundary values for tests: a node held at a displacement until released; a dead load (mN).
  // Throw std::out_of_range for a node outside the mesh.
  void prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm);
  void release_displacement(int node);
  void set_nodal_load(int node, const Eigen::Vector3d& force_mn);
  // Equilibrium for the boundary values and loads, without a probe (step(nullptr, 0) keeps
  // last frame's probe contacts released).
  HyperelasticSolveStats solve();

  // The force the outside exerts on a node to hold it where it is (mN): ∂E/∂x − load. Zero at a
  // free node in equilibrium; the reaction at a held one.
  Eigen::Vector3d reaction_force_mn(int node) const;
  const HyperelasticSolveStats& last_solve_stats() const { return last_; }
  // Nodes the probe pushed at the end of the last step.
  std::span<const int> probe_contact_nodes() const { return contact_nodes_; }

  int node_count() const { return static_cast<int>(rest_.size()); }
  int tet_count() const { return static_cast<int>(tets_.size()); }

 private:
  struct Factor;  // CHOLMOD's, kept out of this header

  void build_pattern();
  // Newton to equilibrium with the current held set (free forces below relative_tolerance × the
  // largest held force); returns false when it did not converge.
  bool newton(int max_iterations, double relative_tolerance);
  // Per-tet forces and (if `with_tangent`) projected tangents into gradient_ and the matrix.
  void assemble(bool with_tangent);
  // Energy of positions x + alpha·step over all tets; +inf if a tet would invert.
  double energy_along(double alpha);
  // Node and tet at x + alpha·step.
  Eigen::Vector3d position_along(int node, double alpha) const;
  double tet_energy_uj(int t, double alpha) const;
  bool all_tets_positive_along(double alpha);
  void scatter_tangents();
  // The probe's frictionless contact, an augmented Lagrangian per free node: the push
  // max(0, λ − k·d) (mN, d the node's signed distance outside the probe), its energy, and the
  // gradient and Gauss–Newton tangent added to the system.
  double contact_push_mn(int node, const Eigen::Vector3d& x) const;
  double contact_energy_uj(int node, const Eigen::Vector3d& x) const;
  void add_contact_terms(bool with_tangent);
  double max_push_mn() const;
  // Moves every multiplier to its node's push; returns the deepest penetration (mm).
  double update_multipliers();
  void refresh_targets();
  void store_displacements();
  template <typename Body>
  void for_each_chunk(int count, Body&& body) const;

  std::vector<Eigen::Vector3d> rest_;
  std::vector<std::array<std::int32_t, 4>> tets_;
  std::vector<HyperelasticLaw> laws_;
  std::vector<Eigen::Matrix3d> rest_shape_inverse_;  // Dm⁻¹ per tet
  std::vector<double> rest_volume_;
  std::vector<std::uint8_t> fixed_;
  HyperelasticSettings settings_;
  hal::JobSystem* jobs_ = nullptr;

  std::vector<Eigen::Vector3d> x_;  // current positions
  Eigen::VectorXd u_;               // x − rest, node-major
  std::vector<Eigen::Vector3d> last_good_;

  // Held nodes and where they go: fixed (rest), prescribed, probe contacts.
  std::vector<std::uint8_t> held_;
  std::vector<Eigen::Vector3d> target_;
  std::vector<std::uint8_t> prescribed_;
  std::vector<Eigen::Vector3d> prescribed_displacement_;
  const ProbeCollider* probe_ = nullptr;  // during a step
  std::vector<int> contact_nodes_;        // nodes the probe pushed at the end of the last step
  std::vector<double> contact_multiplier_mn_;
  std::vector<double> contact_stiffness_;  // penalty k per node, mN/mm
  Eigen::VectorXd load_;

  // Tangent storage: upper triangle, CSC over all 3N DOFs; per tet, where its 12×12 entries go.
  std::unique_ptr<Factor> factor_;
  std::vector<std::int32_t> tet_scatter_;  // 144 per tet, −1 below the diagonal
  // Per DOF: its off-diagonal entries (value index, the other DOF of the entry).
  std::vector<std::vector<std::pair<std::int32_t, std::int32_t>>> dof_entries_;
  std::vector<std::int32_t> diagonal_entry_;
  // Per-tet element results, then summed node by node in a fixed order.
  std::vector<Eigen::Matrix<double, 12, 1>> tet_force_;
  std::vector<Eigen::Matrix<double, 12, 12>> tet_tangent_;
  std::vector<std::vector<std::pair<std::int32_t, std::int8_t>>> node_tets_;  // (tet, corner)
  Eigen::VectorXd gradient_;                                                  // ∂E/∂x − load
  Eigen::VectorXd rhs_, step_;
  std::vector<double> chunk_partials_;
  HyperelasticSolveStats last_;
};

}  // namespace ultrasim::sim
