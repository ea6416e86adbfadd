#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cstdint>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/settings.hpp"
#include "ultrasim/sim/sphere_collider.hpp"

namespace ultrasim::sim {

// One node held at a given displacement this frame (a probe contact, or a test's boundary value).
struct PrescribedNode {
  int node = 0;
  Eigen::Vector3d displacement_mm = Eigen::Vector3d::Zero();
};

struct ExactFemSettings {
  // Nodes whose K⁻¹ columns (3 each, one per axis, free-DOF length) are kept between frames. A node
  // that stays in contact reuses its columns; one that comes into contact costs 3 solves with the
  // factor. Memory: 24 bytes × free DOFs per node (≈ 0.6 MB at 32×16×16). Nodes in the current
  // frame's set are never evicted, so the cache may exceed this while more nodes are in contact.
  int max_cached_nodes = 256;
};

// What one solve did. Counters, not clocks (app/sim reads no clock): the costly work is
// factorisations (once, at construction) and triangular solves with the factor.
struct ExactFemStepStats {
  int contact_nodes = 0;         // nodes prescribed this frame (fixed nodes are not counted)
  double contact_force_n = 0.0;  // |sum of reaction forces on the prescribed nodes|, newtons
  int columns_computed = 0;      // K⁻¹ columns solved for this frame (3 per newly held node)
  int columns_reused = 0;        // K⁻¹ columns taken from the cache
  int load_solves = 0;           // solves for the nodal loads (1 after loads change, else 0)
  int condensed_size = 0;        // size of the dense capacitance system, 3 × contact_nodes
};

// Exact quasi-static linear FEM: the same model as LinearFem (linear tets, Cauchy strain,
// isotropic materials; K in kPa·mm so K u is in mN) solved exactly instead of by a few CG steps.
//
// The stiffness restricted to the free DOFs (all but fixed nodes) is factored once, at
// construction, with a sparse LDLᵀ (Eigen::SimplicialLDLT, AMD ordering). Nodes held at a
// displacement change every frame (probe contact), so they are not eliminated from the factor;
// they are imposed by condensation onto the held DOFs instead (capacitance matrix / Schur
// complement of the Lagrange-multiplier system):
//   u = K⁻¹ f + Z λ,  Z = K⁻¹ E,  (Eᵀ Z) λ = d − Eᵀ K⁻¹ f,
// where E selects the held DOFs, d their displacements and λ their reaction forces (mN). Z's
// columns are cached per node, so a node that stays in contact costs nothing; the dense system is
// 3·held × 3·held. The result equals a direct solve with the held DOFs eliminated, to rounding.
//
// Single-threaded. Construction allocates; solve() allocates when a node's columns enter the
// cache and when the number of held nodes changes (the dense capacitance system is resized).
class ExactFem {
 public:
  // tet_materials: one per tet; fixed_nodes: one flag per node (nonzero = fixed at zero).
  // Throws std::invalid_argument when no node is fixed ("... singular ..."), a tet has no positive
  // volume, a material is out of range, or the factorisation fails (stiffness singular).
  ExactFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
           std::span<const std::uint8_t> fixed_nodes, const ExactFemSettings& settings = {});

  // External force on a node, mN, applied from the next solve on; ignored on fixed nodes.
  void set_nodal_load(int node, const Eigen::Vector3d& force_mn);
  void clear_nodal_loads();

  // Solves the static problem with the given nodes held at their displacements (mm) and the
  // current nodal loads. Nodes must be distinct; fixed nodes in the list are skipped (held at 0).
  // Throws std::out_of_range for a node outside the mesh, std::invalid_argument when the dense
  // system is not positive definite (a node listed twice).
  ExactFemStepStats solve(std::span<const PrescribedNode> held);

  // The published sphere collider, exact: nodes inside the sphere at their last deformed position
  // are held at their radial projection onto its surface, then solve().
  ExactFemStepStats step(const SphereCollider& collider);

  Eigen::Vector3d displacement_mm(int node) const { return u_.segment<3>(3 * node); }
  // Whole displacement vector, node-major x,y,z, mm.
  const Eigen::VectorXd& displacements_mm() const { return u_; }
  // Reaction force on a held node from the last solve, mN (zero for free nodes).
  Eigen::Vector3d reaction_force_mn(int node) const;
  std::span<const Eigen::Vector3d> deformed_positions_mm() const { return deformed_; }

  const Eigen::SparseMatrix<double, Eigen::RowMajor>& stiffness() const { return stiffness_; }
  int node_count() const { return static_cast<int>(rest_.size()); }
  int free_dof_count() const { return static_cast<int>(free_to_global_.size()); }
  int factorization_count() const { return factorizations_; }
  long long total_columns_computed() const { return total_columns_computed_; }
  int cached_nodes() const { return static_cast<int>(cache_slot_node_.size()); }

 private:
  // Cache slot holding node's 3 columns of K_ff⁻¹ (computing them if missing).
  int columns_for(int node, ExactFemStepStats& stats);
  void update_deformed();

  ExactFemSettings settings_;
  std::vector<Eigen::Vector3d> rest_;
  std::vector<std::uint8_t> fixed_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness_;
  std::vector<int> global_to_free_;  // DOF → free index, −1 for fixed DOFs
  std::vector<int> free_to_global_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> factor_;
  int factorizations_ = 0;
  long long total_columns_computed_ = 0;

  Eigen::VectorXd load_mn_;        // global, mN
  Eigen::VectorXd load_response_;  // K_ff⁻¹ f on free DOFs
  bool loads_dirty_ = false;

  // Column cache: slot s holds node cache_slot_node_[s]'s columns; node_slot_[n] is n's slot or −1.
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 3>> cache_columns_;
  std::vector<int> cache_slot_node_;
  std::vector<int> node_slot_;
  std::vector<int> last_use_;  // per slot, frame counter of last use (evict least recent)
  int frame_ = 0;

  // Per-frame scratch.
  std::vector<int> held_nodes_;
  std::vector<int> held_slots_;
  std::vector<PrescribedNode> contact_scratch_;
  Eigen::MatrixXd capacitance_;
  Eigen::LLT<Eigen::MatrixXd> capacitance_llt_;
  Eigen::VectorXd lambda_mn_, rhs_, u_free_, rhs_free_;
  Eigen::VectorXd u_;         // global displacements, mm
  Eigen::VectorXd reaction_;  // global reactions on held DOFs, mN
  std::vector<Eigen::Vector3d> deformed_;
};

}  // namespace ultrasim::sim
