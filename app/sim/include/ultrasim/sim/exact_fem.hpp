#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/contact.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// One node held at a given displacement this frame (a probe contact, or a test's boundary value).
struct PrescribedNode {
  int node = 0;
  Eigen::Vector3d displacement_mm = Eigen::Vector3d::Zero();
};

// One node kept on a plane this frame: normal · u = displacement_mm, free to slide along the
// plane (frictionless contact: the probe pushes along its surface normal only).
struct NormalConstraint {
  int node = 0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
  double displacement_mm = 0.0;
};

// What one solve did. Counters, not clocks (app/sim reads no clock): the costly work is the
// factorisation and Green's functions (once, at construction) and solves with the factor.
struct ExactFemStepStats {
  int contact_nodes = 0;         // nodes constrained this frame (fixed nodes are not counted)
  double contact_force_n = 0.0;  // |sum of the constraint forces|, newtons
  int columns_computed = 0;      // K⁻¹ columns solved for this frame (3 per newly held node)
  int columns_reused = 0;        // K⁻¹ columns taken from the precomputed or cached ones
  int load_solves = 0;           // solves for the nodal loads (1 after loads change, else 0)
  int condensed_size = 0;        // size of the dense capacitance system (constraint rows)
  int contact_rounds = 0;        // active-set rounds (frictionless probe contact), else 1
};

// Exact quasi-static linear FEM: the same model as LinearFem (linear tets, Cauchy strain,
// isotropic materials; K in kPa·mm so K u is in mN) solved exactly instead of by a few CG steps.
//
// The stiffness on the free DOFs (all but fixed nodes) is factored once, at construction, by
// CHOLMOD's supernodal Cholesky. Probe contacts change every frame, so they are not eliminated
// from the factor; they are imposed by condensation (the capacitance-matrix method of James & Pai,
// ArtDefo, 1999): with constraint rows Eᵀ u = d,
//   u = K⁻¹ f + Z λ,  Z = K⁻¹ E,  (Eᵀ Z) λ = d − Eᵀ K⁻¹ f,
// λ being the constraint forces (mN). Each row is one direction at one node (three axes for a
// held node, the probe's normal for a frictionless contact), so Z is a combination of the node's
// three K⁻¹ columns, its Green's functions.
//
// The Green's functions of the contact candidates (the skin the probe can reach) are computed at
// construction: the field part in float (n_free × 3 per node; 4 bytes × free DOFs × 3 per node,
// ≈ 0.8 MB per skin node at 32×16×16 nodes), the part on the candidates themselves in double, so
// the capacitance system is exact in double and the field is exact to float rounding (≈ 1e-7
// relative). A frame then costs no solve: a small dense Cholesky and one pass over the touched
// nodes' columns. Other nodes get their columns from the factor the first time they are held
// (3 solves) and keep them in a least-recently-used cache.
//
// step() allocates only when the contact set outgrows anything seen before (dense system size)
// or a non-candidate node's columns enter the cache.
class ExactFem final : public DeformationEngine {
 public:
  // tet_materials: one per tet; fixed_nodes: one flag per node (nonzero = fixed at zero);
  // contact_candidates: empty, or one flag per node (nonzero = precompute its Green's functions).
  // `jobs`, if given, must outlive the engine; it splits the per-frame field update and solves
  // for deferred nodes in the background (step_within()).
  // Throws std::invalid_argument when no node is fixed ("... singular ..."), a tet has no positive
  // volume, a material or setting is out of range, or the stiffness is not positive definite.
  ExactFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
           std::span<const std::uint8_t> fixed_nodes, const ExactFemSettings& settings = {},
           std::span<const std::uint8_t> contact_candidates = {}, hal::JobSystem* jobs = nullptr);
  ~ExactFem() override;
  ExactFem(const ExactFem&) = delete;
  ExactFem& operator=(const ExactFem&) = delete;

  // External force on a node, mN, applied from the next solve on; ignored on fixed nodes.
  void set_nodal_load(int node, const Eigen::Vector3d& force_mn);
  void clear_nodal_loads();

  // Solves the static problem with the given nodes held at their displacements (mm) and the
  // current nodal loads. Nodes must be distinct; fixed nodes in the list are skipped (held at 0).
  // Throws std::out_of_range for a node outside the mesh, std::invalid_argument when the dense
  // system is not positive definite (a node listed twice).
  ExactFemStepStats solve(std::span<const PrescribedNode> held);
  // The same with frictionless plane constraints (one row per node; nodes distinct).
  ExactFemStepStats solve(std::span<const NormalConstraint> constraints);

  // DeformationEngine: the probe's contact solved exactly with the configured contact model.
  // frame_dt_s is ignored (quasi-static). A probe pressed so deep that more than
  // max_inverted_fraction of the tets invert keeps the last good shape and reports diverged.
  EngineKind kind() const override { return EngineKind::kExactFem; }
  std::string_view name() const override { return "exact FEM"; }
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  // The same, except that nodes whose Green's functions are neither precomputed (the skin) nor
  // cached are not held (a full solve each, ~30 ms on the default case: more than a frame has);
  // they follow the field and may end up inside the probe, and cut_short says so. Such a node's
  // solve then goes to the job system's background thread (hal::JobSystem::post_background),
  // one node at a time, and a later frame takes its columns into the cache: under a budget on
  // every frame (the kiosk) a deep press past the skin's candidates converges to the exact
  // answer over a few frames per node. Without a background thread, only an unbudgeted step()
  // fills the cache. The budget is asked before each frictionless contact round after one that
  // let no node go; without time the frame shows the last round's answer (nodes it took in still
  // inside the probe) and the next frame carries on from its set.
  EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                              const StepBudget& may_continue) override;
  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return deformed_; }
  // Quasi-static: the next step() solves from scratch; this only sets the shape shown and the
  // positions the next contact search starts from.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  // Nodes the last solve constrained (held, or in contact with the probe).
  std::span<const int> constrained_nodes() const { return row_nodes_; }

  // The last solve's counters (step() fills them too).
  const ExactFemStepStats& last_solve_stats() const { return last_stats_; }

  Eigen::Vector3d displacement_mm(int node) const { return u_.segment<3>(3 * node); }
  // Force the constraints or supports exert on a node in the last solve (K u − f), mN: ~0 for
  // free nodes.
  Eigen::Vector3d reaction_force_mn(int node) const;

  const Eigen::SparseMatrix<double, Eigen::RowMajor>& stiffness() const { return stiffness_; }
  int node_count() const { return static_cast<int>(rest_.size()); }
  int free_dof_count() const { return static_cast<int>(free_to_global_.size()); }
  int factorization_count() const { return factorizations_; }
  long long total_columns_computed() const { return total_columns_computed_; }
  int cached_nodes() const { return static_cast<int>(cache_slot_node_.size()); }
  int contact_candidate_count() const { return static_cast<int>(candidate_nodes_.size()); }

 private:
  struct Factor;                                             // CHOLMOD, kept out of the header
  using Columns = Eigen::Matrix<double, Eigen::Dynamic, 3>;  // one node's K⁻¹ columns
  // One constraint row: direction at a node, target value.
  struct Row {
    int node;
    Eigen::Vector3d direction;
    double value_mm;
  };

  struct BackgroundSolve;  // one node's columns solved off the frame

  void precompute_candidates(std::span<const std::uint8_t> contact_candidates);
  // A cache slot for `node`'s columns (the least recently used one when full), marked used now.
  int take_cache_slot(int node);
  // Frame thread: a finished background solve's columns into the cache; a deferred node's solve
  // to the background when none is under way.
  void adopt_background_solve();
  void request_background_solve(int deferred_node);
  void refresh_load_response(ExactFemStepStats& stats);
  // Makes sure `node` has Green's functions available (precomputed or cached).
  void ensure_columns(int node, ExactFemStepStats& stats);
  // 3×3 block of K_ff⁻¹: rows at node a's DOFs, columns at node b's.
  Eigen::Matrix3d green_block(int a, int b) const;
  // Which displacements a solve updates: all, or only the skin (contact candidates) and the
  // constrained nodes, which is all a contact round looks at.
  enum class Field { kWhole, kSkin };
  // Solves the capacitance system for rows_ and fills the per-node constraint forces and the
  // displacements of `field`.
  ExactFemStepStats solve_rows(Field field);
  void update_whole_field();
  void update_skin_field();
  void accumulate_field();
  EngineStepStats solve_probe(const ProbeCollider* probe, const StepBudget& may_continue);
  EngineStepStats step_frictionless(const ProbeCollider& probe, const StepBudget& may_continue);
  // Under a budget: whether `node` lacks Green's functions and so is not held this frame (marks
  // it deferred).
  bool defers(int node);
  // The frictionless row holding `node` on the probe's tangent plane at `point_mm` (normal ·
  // u = normal · (point − rest)).
  Row tangent_plane_row(int node, const Eigen::Vector3d& point_mm,
                        const Eigen::Vector3d& normal) const;
  // rows_ for a frictionless step's first round: the last step's contacts and the nodes now on
  // or inside the probe (less those let go that are still only on its surface).
  void start_from_last_contacts(const ProbeCollider& probe);
  // The next frictionless step starts from the nodes on or inside the probe only.
  void forget_contacts();
  // What one round of the frictionless active set did to rows_.
  struct ActiveSetChange {
    bool released = false;     // let nodes go that the probe pulled
    bool reprojected = false;  // moved the plane of nodes that slid off the probe's curved rim
    bool taken_in = false;     // held nodes that ended up inside the probe
    bool any() const { return released || reprojected || taken_in; }
  };
  ActiveSetChange update_active_set(const ProbeCollider& probe, bool skin_only);
  void update_deformed();

  ExactFemSettings settings_;
  hal::JobSystem* jobs_ = nullptr;
  std::vector<Eigen::Vector3d> rest_;
  std::vector<std::array<std::int32_t, 4>> tets_;
  std::vector<std::uint8_t> fixed_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness_;
  std::vector<int> global_to_free_;  // DOF → free index, −1 for fixed DOFs
  std::vector<int> free_to_global_;
  std::unique_ptr<Factor> factor_;
  std::unique_ptr<BackgroundSolve> background_;
  int factorizations_ = 0;
  long long total_columns_computed_ = 0;

  Eigen::VectorXd load_mn_;        // global, mN
  Eigen::VectorXd load_response_;  // K_ff⁻¹ f on free DOFs
  bool loads_dirty_ = false;

  // Precomputed Green's functions of the contact candidates.
  std::vector<int> candidate_nodes_;
  std::vector<int> candidate_slot_;       // per node: index in candidate_nodes_, or −1
  Eigen::MatrixXf candidate_green_;       // n_free × 3·candidates
  Eigen::MatrixXd candidate_compliance_;  // 3·candidates × 3·candidates (double)

  // Least-recently-used cache of other nodes' columns (double).
  std::vector<Columns> cache_columns_;
  std::vector<int> cache_slot_node_;
  std::vector<int> node_slot_;
  std::vector<int> last_use_;
  int frame_ = 0;

  // Per-frame state and scratch.
  std::vector<Row> rows_;
  std::vector<int> row_nodes_;                  // distinct constrained nodes, in order
  std::vector<Eigen::Vector3d> node_force_mn_;  // per constrained node: Σ direction·λ
  std::vector<int> node_constrained_index_;     // per node: index in row_nodes_, or −1
  std::vector<NodeContact> contacts_;
  std::vector<std::uint8_t> in_contact_;  // per node, within a frame's active-set rounds
  std::vector<std::uint8_t> released_;    // per node: let go (once a frame; see still_let_go_)
  std::vector<int> last_contacts_;        // nodes the last frictionless step ended holding
  std::vector<int> still_let_go_;         // let go, and still only on the probe's surface
  bool rounds_unfinished_ = false;        // it ran out of time: released_ carries over
  std::vector<std::uint8_t> deferred_;    // per node: not held this frame (no Green's functions)
  bool defer_uncached_ = false;           // inside step_within() with a budget
  Eigen::MatrixXd capacitance_;
  Eigen::LLT<Eigen::MatrixXd> capacitance_llt_;
  Eigen::VectorXd lambda_mn_, rhs_, u_free_, rhs_free_;
  Eigen::VectorXd u_;  // global displacements, mm
  Eigen::VectorXd last_good_u_;
  std::vector<Eigen::Vector3d> deformed_;
  ExactFemStepStats last_stats_;
};

}  // namespace ultrasim::sim
