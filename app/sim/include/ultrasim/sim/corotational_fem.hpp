#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/contact.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/settings.hpp"
#include "ultrasim/sim/sliding_nodes.hpp"

namespace ultrasim::sim {

// What solve_to_convergence() did.
struct CorotationalConvergence {
  bool converged = false;       // the last rotation update moved no node by tolerance or more
  int outer_iterations = 0;     // rotation updates (each followed by a linear solve)
  int pcg_iterations = 0;       // over all outer iterations
  double last_change_mm = 0.0;  // largest nodal displacement change of the last outer iteration
  EngineStepStats stats;        // of the final state, as step() reports it
};

// Quasi-static corotational linear FEM ("stiffness warping", Müller & Gross 2004, element-based).
// Each tet keeps the linear stiffness K_e of LinearFem (tet_stiffness()) but applies it in its own
// rotated frame: with R the rotation of the tet's deformation gradient (polar decomposition),
// the force that holds the tet's nodes at x is f_e = R K_e (Rᵀ x − x0). Rigid rotations therefore
// cost no energy, which is what keeps large rotations from inflating the tissue as linear FEM
// (Cauchy strain) does.
//
// Each frame: contacts are found on the last frame's shape (nodes inside the probe are put at
// the collider's push-out target and held there, or, under the default Coulomb slip, held along
// the probe's normal only and left to slide in the CG as the PCG FEM's; fixed nodes at rest), every
// tet's rotation is extracted from the shape with those nodes moved (a tet whose deformation
// gradient has turned less than settings.rotation_update_tolerance from its rotation keeps it,
// and of those turned further at most settings.max_rotation_updates_fraction of all tets, the
// most turned, take theirs; with settings.rotation_update_interval_frames above 1, only in the
// steps of its phase, the others solving the last system), the warped stiffness
// K_R = Σ R K_e Rᵀ is assembled into a
// block-sparse matrix whose pattern and scatter map were built once (only the blocks of tets
// whose rotation changed are brought up to date: while few tets moved
// (settings.term_swap_max_fraction), each moved tet's old terms swapped for its new ones, else the
// blocks of the rows they hold summed again), and
// K_R u = Σ R K_e (x0 − Rᵀ x0) + loads is solved on the free DOFs by Jacobi-preconditioned CG with
// a fixed iteration budget, warm-started from the last frame. So each frame's rotations lag its
// solve by one frame; solve_to_convergence() repeats rotations and solves until the shape stops
// changing: the reference the per-frame method's lag is measured against.
//
// Units: mm, kPa, mN. With a JobSystem, the per-tet rotations, the assembly and the CG vector
// work are split into fixed chunks; every sum is taken in chunk order, so results are bitwise the
// same with and without jobs, whatever the thread count. step() does not allocate.
class CorotationalFem final : public DeformationEngine {
 public:
  // tet_materials: one per tet; fixed_nodes: one flag per node (nonzero = held at rest).
  // Throws std::invalid_argument when no node is fixed ("... singular ..."), a tet references a
  // node outside the mesh or has no positive rest volume, a material is out of its physical
  // range, or the settings are out of range; std::logic_error if its element stiffness ever
  // stops matching tet_stiffness() (a model change made in one place only). Allocates.
  CorotationalFem(const geometry::TetMesh& mesh, std::span<const Material> tet_materials,
                  std::span<const std::uint8_t> fixed_nodes, const CorotationalSettings& settings,
                  hal::JobSystem* jobs = nullptr);

  EngineKind kind() const override { return EngineKind::kCorotationalFem; }
  std::string_view name() const override { return "corotational FEM"; }

  // A contact that slides this frame (HeldContactSettings): its normal and friction.
  const SlidingHold* sliding_hold(int node) const override { return sliding_.hold(node); }

  // Volume stitching (StitchedVolume), as the PCG FEM's: an anchor adds k I to its node's row of
  // the system and k (target − rest) to its rhs (outside the warped blocks, so moving anchors
  // re-sum nothing). The coarse and fine corrections: the rest stiffness (LinearFem's; the
  // coarse operator and the fine one's preconditioner), the warped one's product (the fine
  // correction's steps), the tissue's force Σ R K_e (x0 − Rᵀ x0) − K_R u with the rotations the
  // tets hold, the held nodes (fixed, prescribed, on the probe), moves of the free ones (the
  // sliding ones in their tangent planes) and of a held one.
  bool supports_anchor_springs() const override { return true; }
  void set_anchor_springs(std::span<const AnchorSpring> anchors) override;
  Eigen::SparseMatrix<double, Eigen::RowMajor> rest_stiffness_mn_per_mm() const override;
  // K_R v (the last assembly's warped blocks; no anchors), on the calling thread.
  bool tangent_stiffness_times(const Eigen::VectorXd& v_mm, Eigen::VectorXd& out_mn) const override;
  void tissue_forces_mn(Eigen::VectorXd& forces_mn) const override;
  bool holds_node(int node) const override {
    return fixed_[node] != 0 || prescribed_[node] != 0 || held_[node] != 0 || sliding_.slides(node);
  }
  void displace_free_nodes_mm(const Eigen::VectorXd& du_mm) override;
  void move_held_node_mm(int node, const Eigen::Vector3d& position_mm) override;

  // One frame: contacts, rotations and assembly (in the update interval's steps),
  // pcg_iterations_per_frame CG iterations.
  // Contacts (an active set updated once a frame): nodes inside the probe, or left on its
  // surface, are held at its push-out target; nodes it pushed on last frame stay on its surface
  // as it lifts, until holding them would take a pull; nodes it had to pull on are let go.
  // Recovery, with the other engines' tolerance: a frame may leave inverted tets up to
  // settings.max_inverted_fraction of all tets (a few folded under the probe's rounded rim), or
  // as many as the shape it started from had if that was more (a folded shape handed over by
  // another engine), but no more, and no non-finite value. A frame over that is cut short along
  // its update (1/2, 1/4, ... of it, the first within the limit), or all the way back to the
  // previous frame's shape, and reports diverged with Recovery::kSubstepped (cause: inverted);
  // inverted_tets counts the shape it ends with, as for any frame. A frame within the limit
  // reports its inverted tets but not diverged. Tets with all four nodes held or sliding on the
  // probe (pressed flat between contacts) are the constraints' doing: they are counted in
  // inverted_tets but never against the limit. Nothing resets to rest: with the probe still deep in
  // the tissue, rest would put nodes far inside it. frame_dt_s is ignored.
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  // The clock rotation_update_interval_frames' phase is read against for the next step (by
  // default the engine's own steps, counted from construction): a stitched volume sets its own
  // exchanges', so that its sub-volumes update in turn whichever of them step.
  void set_update_clock(std::int64_t step) { step_count_ = step; }
  // The next step, if its update is due, solves the last warped system instead (its time better
  // spent on the CG: a stitched batch whose share is short), unless settings.max_update_turns_held
  // due updates in a row were held already; the first step and the first after set_displacements
  // update whatever. Asked of one step only.
  void hold_next_update() { hold_next_update_ = true; }
  // Whether a step on the update clock `step` (set_update_clock) would bring the warped system
  // up to date whatever hold_next_update() asks: its update due with max_update_turns_held held
  // in a row already, or the first step (since construction or set_displacements).
  bool update_forced_at(std::int64_t step) const;
  // Whether the last step brought the warped system up to date (rotation_update_interval_frames),
  // and whether it held a due update (hold_next_update).
  bool warped_system_updated() const { return warped_system_updated_; }
  // How many steps brought the warped system up to date since construction.
  std::int64_t warped_system_updates() const { return warped_system_updates_; }
  bool update_held() const { return update_held_; }
  // Fewer CG iterations when the budget runs out (one at least); contacts every frame, rotations
  // and the assembly as in step(). A frame inverted over the limit tries its shorter updates
  // while the budget allows, and then goes back to the previous frame's shape (cut_short).
  EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                              const StepBudget& may_continue) override;

  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return deformed_; }

  // Live switch. Fixed nodes stay at zero; the old contacts are let go; the rotations are kept
  // (the next step extracts those the new shape has turned by the tolerance). Throws
  // std::invalid_argument when u_mm does not have 3 × node count entries or holds a non-finite
  // value.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  // Holds a node at a displacement (mm) from the next step or solve on, until released; ignored
  // for fixed nodes. For boundary-value tests (patch tests, a cantilever's tip). Does not
  // allocate. Throws std::out_of_range for a node outside the mesh.
  void prescribe_displacement(int node, const Eigen::Vector3d& displacement_mm);
  void release_displacement(int node);

  // External force on a node, mN, fixed in direction (a dead load), from the next step or solve
  // on; ignored on fixed nodes. For tests (a loaded cantilever). Throws std::out_of_range for a
  // node outside the mesh, std::invalid_argument for a non-finite force.
  void set_nodal_load(int node, const Eigen::Vector3d& force_mn);
  void clear_nodal_loads();

  // The converged corotational answer for the current constraints (fixed, prescribed, and the
  // last step's contacts held at their targets): repeats rotation extraction and a linear solve
  // (CG to a relative residual of 1e-12) until no node moves by `tolerance_mm` or more, or
  // `max_outer` rotation updates. For tests and accuracy reports; does not allocate.
  CorotationalConvergence solve_to_convergence(double tolerance_mm, int max_outer);

  // The force each node needs from outside to hold the tissue at `positions_mm`, mN, node-major
  // x,y,z: Σ R K_e (Rᵀ x − x0) with every tet's rotation taken from those positions. Zero for a
  // rigid motion of the whole mesh; at equilibrium, the load where nodes are loaded, the
  // reaction where they are held, zero elsewhere. `forces_mn` is resized to 3 × node count.
  // Serial; for tests and reports.
  void elastic_forces_mn(std::span<const Eigen::Vector3d> positions_mm,
                         Eigen::VectorXd& forces_mn) const;

  // Tets whose volume at the current shape is not positive.
  int inverted_tet_count() const;

  // The warped stiffness of the last assembly (before the first step: the rest stiffness, which
  // equals LinearFem's), as an Eigen matrix. Allocates; for tests.
  Eigen::SparseMatrix<double, Eigen::RowMajor> warped_stiffness() const;

  const CorotationalSettings& settings() const { return settings_; }
  // Rotation of tet t at the last assembly.
  const Eigen::Matrix3d& tet_rotation(int t) const { return rotation_[t]; }
  // Tets whose rotation the last step (or the last outer iteration of solve_to_convergence())
  // extracted anew; the others kept theirs (settings.rotation_update_tolerance and
  // settings.max_rotation_updates_fraction).
  int rotations_updated() const { return rotations_updated_; }

  int node_count() const { return static_cast<int>(rest_.size()); }
  int tet_count() const { return static_cast<int>(tets_.size()); }
  int fixed_node_count() const { return fixed_count_; }
  // Node blocks (3×3) stored in the warped stiffness: its pattern, fixed at construction.
  int stiffness_block_count() const { return static_cast<int>(block_col_.size()); }

 private:
  // Setup (allocates).
  void precompute_tets(std::span<const Material> tet_materials);
  // Throws std::logic_error when tet t's gradient-form stiffness is not tet_stiffness().
  void check_against_linear_fem(int t, const Material& m) const;
  void mark_constrained_rows();
  void build_pattern_and_scatter_map();

  // One frame's pieces (no allocation).
  // Finds this frame's contacts, then holds the constrained nodes.
  void apply_constraints(const ProbeCollider* probe);
  // Appends last frame's pushed nodes that the probe has moved away from, on its surface.
  void add_followers(const ProbeCollider& probe);
  // Drops the followers (contacts_ from first_follower on) that holding would need a pull for.
  void let_go_of_followers_that_would_pull(int first_follower);
  // HeldContactModel::kCoulombSlip: marks the contacts that slide this frame (coulomb_hold()),
  // held along the probe's normal only; stop_sliding() forgets last frame's.
  void choose_sliding_nodes();
  void stop_sliding();
  // Row `node` of K_R (the last assembly) times v.
  Eigen::Vector3d warped_row_times(int node, const Eigen::VectorXd& v) const;
  // sum + the element terms R K_e (x0 − Rᵀ x0) of every tet holding the node.
  Eigen::Vector3d add_element_forces(int node, Eigen::Vector3d sum) const;
  // Global block k (on or above the diagonal) summed from its tets' blocks with these gradients
  // (the rotated ones: K_R's block; the rest ones: K's).
  Eigen::Matrix3d summed_block(int k,
                               const std::vector<Eigen::Matrix<double, 3, 4>>& gradients) const;
  // Blocks in K_R's pattern as a sparse matrix (allocates).
  Eigen::SparseMatrix<double, Eigen::RowMajor> node_blocks_as_matrix(
      const std::vector<Eigen::Matrix3d>& blocks) const;
  // K_R u − b at a node with the last assembly and the anchors: the force holding it there, mN.
  Eigen::Vector3d node_force_mn(int node) const;
  // Marks fixed, prescribed and contact nodes held and puts them at their displacements (a
  // sliding contact, as marked, keeps its own).
  void hold_constrained_nodes();
  // Extracts the rotation of every tet whose deformation gradient has turned `tolerance` radians
  // or more from its rotation (every tet with 0), or of the `max_updates` most turned of them
  // where there are more (besides those whose turn is infinite: inverted, collapsed, or not near
  // any rotation of the one held, which always take one), and marks those in rotation_moved_.
  // A tet found within the tolerance at its last check is checked in one call of
  // `check_interval` (one past it, lost or given a new rotation: at the next call; every tet
  // after set_displacements_mm()), so a tet that turns or is lost between its checks takes its
  // rotation up to check_interval − 1 calls late.
  void update_rotations(double tolerance, int max_updates, int check_interval);
  // A step between the warped system's updates (rotation_update_interval_frames): no tet's
  // rotation moves, a lost one's neither.
  void keep_rotations();
  // settings.max_rotation_updates_fraction of the tets (one at least).
  int rotation_update_cap() const;
  // Tet t's deformation gradient at the current displacements.
  Eigen::Matrix3d deformation_gradient(int t) const;
  // Takes f's rotation for tet t, with its rotated gradients and element rhs.
  void extract_rotation(int t, const Eigen::Matrix3d& f);
  // How K_R is brought up to date for the rotations_updated_ tets marked in rotation_moved_
  // (node_moved_ from them; every node when every tet moved): their terms swapped (moved_tets_
  // lists them, and their terms with the rotations they still hold are taken out here, before
  // their new ones are extracted), or, past settings.term_swap_max_fraction of the tets, the
  // moved rows' blocks summed again.
  void prepare_block_updates();
  // sign × the terms of the tets in moved_tets_ added to their blocks above the diagonal and to
  // the rhs, with their rotated gradients and element rhs.
  void add_moved_tets_terms(double sign);
  // Brings K_R and the rhs up to date as prepared (the swapped tets' new terms added, or the
  // moved rows' blocks and rhs summed again; every node's rhs after a load changed), and the
  // preconditioner of the nodes a moved tet holds.
  void assemble_warped_system();
  struct PcgResult {
    int iterations = 0;
    double relative_residual = 0.0;
    bool cut_short = false;  // the budget stopped it
  };
  PcgResult run_pcg(int max_iterations, double tolerance, const StepBudget& may_continue);
  // The CG's start reads K u from tissue_product_ instead of a product with K (half of a step
  // that keeps its rotations: one product at the start, one an iteration). Computed afresh when
  // it is not known (or its blocks all changed), every tissue_product_refresh_steps solves, or
  // when more than an eighth of the nodes moved since; else brought up to date column by
  // column for the nodes that moved outside the CG (held nodes, followers let go).
  void sync_tissue_product();
  void compute_tissue_product();
  // After a solve: K u from the residual the CG kept (r = b − K u − a∘u on a free row), a
  // product only on held and sliding rows (there r is 0 or projected).
  void carry_tissue_product();
  // After an assembly: the rows whose blocks changed, K u again at tissue_product_u_.
  void update_tissue_product_rows();
  // |Σ reaction over the contacts|, N; stores each contact's push for the next frame.
  double measure_contact_forces();
  // Inverted tets (with a free node) a frame may leave: max_inverted_fraction of all tets.
  int inversion_limit() const;
  // Accepts the new shape, or recovers from a non-finite one or one inverted over the limit
  // (the shorter updates only while may_continue() allows; then the previous shape, cut short);
  // fills the stats. Reads the new shape from the deformed positions, and leaves them at the
  // shape it keeps.
  void accept_or_recover(EngineStepStats& stats, const StepBudget& may_continue);
  void update_deformed();
  // The Jacobi preconditioner's entries at a node: its diagonal block's and its anchor's.
  void update_inverse_diagonal(int node);
  struct InversionCount {
    int total = 0;
    int with_free_node = 0;  // the solver's doing; tets with all four nodes on the probe are not
  };
  // At rest + u, or at the deformed positions (update_deformed: half the memory read, the same
  // sums, so the same count).
  InversionCount count_inverted(const Eigen::VectorXd& u) const;
  InversionCount count_inverted_deformed() const;
  template <typename Position>
  InversionCount count_inverted_at(Position position) const;

  // Runs body(chunk) for chunk in [0, chunks): on the job system when there is one.
  template <typename Body>
  void for_each_chunk(int chunks, Body&& body) const;
  int tet_chunks() const;
  int node_chunks() const;
  // The tets or nodes of a chunk: [first, end).
  std::pair<int, int> tet_range(int chunk) const;
  std::pair<int, int> node_range(int chunk) const;
  // Sums chunk_sums_[0, chunks) in chunk order: the same order on any thread count.
  Eigen::Vector4d sum_chunks(int chunks) const;

  CorotationalSettings settings_;
  hal::JobSystem* jobs_ = nullptr;

  // Mesh and material data, fixed at construction.
  std::vector<Eigen::Vector3d> rest_;
  std::vector<geometry::Tet> tets_;
  std::vector<std::uint8_t> fixed_;
  int fixed_count_ = 0;
  // Per tet: the shape functions' gradients at rest (columns, one per node) and (λV, μV). They
  // give tet_stiffness()'s blocks K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I), which the
  // constructor checks; with R g in place of g, the warped blocks R K_ab Rᵀ.
  std::vector<Eigen::Matrix<double, 3, 4>> shape_gradients_;
  std::vector<Eigen::Vector2d> lame_volume_;

  // Warped stiffness, block CSR over nodes: row n's blocks are [block_row_start_[n],
  // block_row_start_[n+1]), columns block_col_ ascending, values block_value_.
  std::vector<int> block_row_start_;
  std::vector<int> block_col_;
  std::vector<int> diagonal_block_;  // per node: index of its diagonal block
  std::vector<int> mirror_block_;    // per block below the diagonal: its mirror above; else −1
  std::vector<Eigen::Matrix3d> block_value_;
  // Scatter map, stored gather-wise so rows assemble in parallel without races: global block k
  // (on or above the diagonal) sums the element blocks contribution_[contribution_start_[k] ..
  // [k+1]), each encoded as tet × 16 + a × 4 + b.
  std::vector<int> contribution_start_;
  std::vector<std::int32_t> contribution_;
  // Per tet: its blocks above the diagonal for its node pairs (a, b), a ≤ b in (0,0), (0,1), …,
  // (3,3) order, each as an offset into the row of the pair's lower node.
  std::vector<std::array<std::uint16_t, 10>> tet_blocks_;

  // Per-frame state.
  std::vector<Eigen::Matrix3d> rotation_;                       // per tet
  std::vector<Eigen::Matrix<double, 3, 4>> rotated_gradients_;  // per tet: R g_a
  std::vector<Eigen::Matrix<double, 3, 4>> element_rhs_;        // per tet: R K_e (x0 − Rᵀ x0)
  std::vector<std::uint8_t> rotation_moved_;  // per tet: rotation extracted at the last update
  std::vector<double> turn_;                  // per tet: its turn at its last check
  std::int64_t turn_check_frame_ = 0;         // update_rotations() calls so far
  std::int64_t step_count_ = 0;  // the update interval's clock: steps, or set_update_clock()
  bool warped_system_updated_ = false;
  std::int64_t warped_system_updates_ = 0;
  bool hold_next_update_ = false;
  bool update_held_ = false;
  int updates_held_in_a_row_ = 0;
  bool check_every_tet_ = true;       // the next update checks every tet's turn
  std::vector<double> turn_scratch_;  // the turns past the tolerance (capacity: tets)
  // The tets whose terms the last update took out of K_R's blocks, in tet order, until the
  // assembly adds their new ones (capacity: every tet); else the moved rows' blocks are summed
  // again at the assembly.
  std::vector<int> moved_tets_;
  bool sum_moved_rows_again_ = true;
  std::vector<std::uint8_t> node_moved_;  // per node: held by a tet whose rotation moved
  bool loads_changed_ = true;             // since the last assembly: every rhs again
  int rotations_updated_ = 0;
  Eigen::VectorXd u_, rhs_, inverse_diagonal_;
  Eigen::VectorXd r_, z_, p_, q_, u_before_step_;
  std::vector<std::uint8_t> held_;  // fixed, prescribed or in contact this frame
  std::vector<std::uint8_t> prescribed_;
  std::vector<Eigen::Vector3d> prescribed_u_;
  Eigen::VectorXd load_mn_;  // dead nodal loads, node-major
  // Anchor springs (set_anchor_springs): per DOF k, and k (target − rest); the nodes that have one.
  Eigen::VectorXd anchor_stiffness_, anchor_load_mn_;
  std::vector<int> anchored_nodes_;
  std::vector<int> next_anchored_nodes_;  // set_anchor_springs' new list, then swapped
  std::vector<NodeContact> contacts_;
  std::vector<double> contact_push_mn_;  // per node: last frame's push along the probe's normal
  // The contacts that slide this frame; per node chunk, whether it holds one.
  SlidingNodes sliding_;
  std::vector<std::uint8_t> chunk_slides_;
  // K_R u on every row but the fixed nodes', without the anchors, at u = tissue_product_u_
  // (sync_tissue_product); tissue_product_age_: solves since it was computed afresh.
  Eigen::VectorXd tissue_product_, tissue_product_u_;
  bool tissue_product_known_ = false;
  int tissue_product_age_ = 0;
  std::vector<int> moved_nodes_;  // sync_tissue_product's scratch (capacity: every node)
  // Per node: a column of its row is held or slides this solve (mark_constrained_rows).
  std::vector<std::uint8_t> meets_constraint_;
  std::vector<Eigen::Vector3d> deformed_;
  // Per chunk partial sums of a pass (dot products, counts), combined by sum_chunks().
  mutable std::vector<Eigen::Vector4d> chunk_sums_;
};

}  // namespace ultrasim::sim
