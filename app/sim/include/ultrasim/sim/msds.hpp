#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/contact.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

namespace msds_detail {
class ImplicitLattice;
class TaskTeam;
class TetLattice;
}  // namespace msds_detail

// One spring of the mass-spring-damper system: a unique tet edge.
struct MsdsSpring {
  std::int32_t a = 0;  // node indices, a < b
  std::int32_t b = 0;
  double rest_length_mm = 0.0;
  // Σ over the tets sharing the edge of E_tet × stiffness_per_modulus_mm (kPa·mm = mN/mm).
  double stiffness_mn_per_mm = 0.0;
  // stiffness × damping_per_stiffness_s, mN·s/mm; acts on the relative velocity along the spring.
  double damping_mn_s_per_mm = 0.0;
};

// How the MSDS advances in time.
enum class MsdsIntegrator {
  kExplicitEuler,  // (b) as published: forward Euler; stable only below the bound below
  kImplicitEuler,  // (e) backward Euler, linearised each step (Baraff & Witkin 1998); any step
};

// Gershgorin bound on the largest eigenvalue ω² of M⁻¹K (1/s²), K the springs linearised about
// the rest positions, over the free DOFs: the largest absolute row sum of M⁻¹K. `pinned` flags
// nodes that never move (their rows and columns drop out). See msds.cpp for the derivation.
double msds_max_omega_squared_bound(std::span<const Eigen::Vector3d> rest_positions_mm,
                                    std::span<const MsdsSpring> springs,
                                    std::span<const double> node_masses_kg,
                                    std::span<const std::uint8_t> pinned);

// The largest ω² (1/s²) whose mode forward Euler keeps stable at `time_step_s`: the inverse of
// forward_euler_stable_time_step_s. 0 when no mode is (dt ≥ β, or β = 0).
double msds_max_stable_omega_squared(double time_step_s, double damping_per_stiffness_s);

// Largest forward-Euler step (s) that keeps a mode of angular frequency² `omega_squared` stable
// when the damping is stiffness-proportional (C = β K, β = damping_per_stiffness_s):
//   β ω ≤ 2 (underdamped):  dt ≤ β
//   β ω > 2 (overdamped):   dt ≤ 4 / (β ω² + ω √(β² ω² − 4))   (≈ 2 / (β ω²) when β ω ≫ 2)
// Non-increasing in ω², so the bound of the stiffest mode is the bound of the system. β = 0
// gives 0: forward Euler is unconditionally unstable on an undamped oscillator.
double forward_euler_stable_time_step_s(double omega_squared, double damping_per_stiffness_s);

// The mass-spring-damper system (MSDS) on a tet mesh: every unique tet edge a linear spring of
// rest length = edge length with damping along it; each tet sharing the edge adds
// k = E_tet × stiffness_per_modulus_mm and c = k × damping_per_stiffness_s. Lumped masses: a
// quarter of each tet's volume × density to each of its nodes.
//
// A frame is steps_per_frame steps of time_step_s (as published: the simulated time per frame is
// steps × dt whatever the frame lasted; frame_dt_s is ignored). Each step, as published, first
// puts the free nodes inside the probe on its surface (find_contacts) and holds them there for the
// step with zero velocity (the probe is still within a frame); a node only touching the surface
// whose springs pull it away from the probe is let go (the probe can push, not pull). Fixed nodes
// never move.
//
// Divergence: an attempt at the frame stops at the first step that leaves a non-finite value,
// kinetic energy above kinetic_energy_ceiling_uj(), inverted tets or a node past its own speed
// ceiling (the last two checked after every implicit step but the first, every 4th explicit one
// and the last: the first step takes the probe's whole move since the last frame and may fold
// tets under it for that one step). The frame is then re-run from its start with the step
// halved, up to kMaxHalvings times (Recovery::kSubstepped); if every try fails, the tissue is
// reset to rest (Recovery::kReset) after a blow-up, or kept at the frame's start, at rest, when
// the tries failed only on inverted tets or a runaway node (Recovery::kKeptLastGood: a probe
// folding tets under its rim, which no step size fixes). A node that ran away is weighed: its
// mass scaled again for its springs as stretched at the frame's start, for the engine's life
// (node_masses_kg() and mass_scale() change with it). All set diverged and cause; inverted_tets
// counts the first attempt's inverted tets when the frame was kept or reset, the frame's own
// when it stands. A shape that starts a frame over the limit (folds handed over by another
// engine, or kept) may end it with up to as many, not more: else every frame would be refused
// and the folds could never unfold (as the corotational FEM). And the inverted tets refuse a
// frame only while the probe holds tissue: untouched, a relaxing lattice's folds are its own,
// and keeping its start would only stop it relaxing. The
// displacements shown are always finite. Each frame starts again at time_step_s: a step past the
// limit is caught again, every few frames.
//
// Forward Euler past its limit, in the overdamped regime of soft tissue (β ω ≫ 2), blows up a
// mode that is nearly all velocity (positions move by v·dt): the kinetic energy grows ~3× a step
// while the shape stays sane, and the ceiling catches it within a frame or two. The tissue's
// overdamped modes all relax with time constant damping_per_stiffness_s (0.1 s published).
// The published step (5 ms) is 10³–10⁵× the explicit limit with physical masses (7e-8 s on a
// 32×16×16 grid of soft tissue): there the explicit engine resets every frame the probe touches,
// and at a stable step it simulates microseconds a frame, too little to follow a moving probe.
// The implicit one is the usable MSDS; it is stable with any steps_per_frame, 1 included.
//
// Explicit Euler's speed (the published configuration runs 20 steps a frame):
//   - Layout: springs are grouped by node-index offset ("diagonals", msds_spring_lattice.hpp) and
//     tets by node-offset pattern (msds_tet_lattice.hpp), so that on a grid mesh the kernels read
//     positions with plain SIMD loads instead of gathering them; springs and tets of other meshes
//     are handled one by one. Each step is one fused pass over node blocks: the block's spring
//     forces, their per-node sums, the contact release and the update.
//   - SIMD: AVX2 where the CPU has it, picked at run time (the build targets baseline x86-64),
//     else portable std::experimental::simd; both do the same IEEE operations in the same order,
//     so results do not depend on which runs (msds_kernels.hpp).
//   - Single precision where it is safe: positions and velocities are kept in double and mirrored
//     to float each step; each spring's force is computed and summed per node in float (rounding
//     ~1e-7 of a spring's force: ≤ 2e-4 of the motion against a naive double reference over tens
//     of steps, msds_reference_test.cpp). The update, energies, contacts, the inversion count
//     (exact) and every diagnostic are in double; the implicit integrator is all double.
//   - Contacts: only nodes that may have reached the probe are queried. Each node keeps a lower
//     bound of its distance to the probe (the probe's signed distance changes no faster than the
//     node moves), and a frame's first step queries spatial clusters of nodes before nodes.
//
// Implicit Euler's speed: the same diagonals, in double (msds_implicit_lattice.hpp): each spring's
// direction, forces and block computed once a step, the CG's product once per spring, the CG's
// vectors by coordinate, all in plain loops the compiler vectorises (a baseline and an AVX2
// build, bitwise alike, msds_implicit_kernels.hpp). A 15³ stitched sub-volume's step: the springs
// 250 → 110 µs, a CG iteration 112 → 19 µs (docs/benchmarks.md). It runs on one thread.
//
// Units: mm, kPa, mN, kg, s (mN = kg·mm/s²); energies in µJ (mN·mm). With a JobSystem a frame is
// one JobSystem::run(): its parallel stages are shared among the job system's threads inside that
// run (msds_task_team.hpp; one run per stage cost more than the stage on a 2-core machine). The
// explicit step is split into fixed node ranges (one per thread, each recomputing the springs
// below its start) and the inversion count into fixed chunks; each node sums its own springs and
// every sum is taken in block (chunk) order, so results are bitwise the same with and without
// jobs, whatever the thread count. The implicit integrator ignores the job system (its stages
// are too short to share). step() does not allocate.
class MsdsEngine final : public DeformationEngine {
 public:
  // Frame re-runs with the step halved before giving up and resetting to rest.
  static constexpr int kMaxHalvings = 4;
  // Implicit Euler: Jacobi-preconditioned CG per step, warm-started from the current velocity,
  // stopped at a fraction of the right-hand side or when the residual force (residual / dt) is
  // below kCgForceFloorMn in all (the spring forces' rounding, for stiff tissue on large meshes).
  // Measured on a 32×16×16 grid under a sweeping probe: 1e-3 stays within 0.013 mm of a 1e-10
  // solve for 1 to 20 steps a frame, at a third to a quarter of the iterations of 1e-6.
  static constexpr int kMaxCgIterationsPerStep = 200;
  static constexpr double kCgRelativeTolerance = 1e-3;
  static constexpr double kCgForceFloorMn = 1e-6;

  // tet_materials: one per tet; fixed_nodes: one flag per node (nonzero = held at rest).
  // Throws std::invalid_argument when no node is fixed ("... singular ..."), a tet references a
  // node outside the mesh or has no positive rest volume, a material is out of its physical
  // range, or a setting is out of range. Allocates (every buffer step() needs).
  // `reachable_nodes` (empty or one flag per node): the tissue's surface the probe can touch,
  // whose held nodes may slide along it (HeldContactModel::kCoulombSlip); empty: the mesh's
  // boundary (a stitched sub-volume's includes its seams, which are inside the tissue).
  MsdsEngine(MsdsIntegrator integrator, const geometry::TetMesh& mesh,
             std::span<const Material> tet_materials, std::span<const std::uint8_t> fixed_nodes,
             const MsdsSettings& settings, hal::JobSystem* jobs = nullptr,
             std::span<const std::uint8_t> reachable_nodes = {});
  MsdsEngine(const MsdsEngine&) = delete;
  MsdsEngine& operator=(const MsdsEngine&) = delete;
  ~MsdsEngine() override;

  EngineKind kind() const override;
  std::string_view name() const override;
  // stats: iterations = integration steps (explicit) or CG iterations (implicit) of the accepted
  // run; relative_residual = the largest final CG residual of its steps (implicit); contact_nodes
  // and contact_force_n = the nodes held on the probe after the last step and |Σ| of the spring
  // and damping forces the probe balances on them.
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  // A rejected frame is retried with smaller steps (2×, 4×, ... the steps) only while there is
  // time; the explicit integrator stops stepping when the budget runs out (4 steps at least: the
  // frame then integrates less simulated time), the implicit one's CG stops (one iteration at
  // least; its steps integrate the frame's simulated time in full).
  EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                              const StepBudget& may_continue) override;
  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return x_; }
  // Live switch: starts from u with zero velocity; fixed nodes stay at rest. Throws
  // std::invalid_argument when u_mm does not have 3 × node count entries or is not finite.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  // Anchor springs (volume stitching), both integrators: the explicit one adds their forces to
  // the springs' in its float pass (and, with mass scaling, raises an anchored node's mass for
  // its extra stiffness), the implicit one adds their stiffness and damping to its system.
  bool supports_anchor_springs() const override { return true; }
  void set_anchor_springs(std::span<const AnchorSpring> anchors) override;

  // Coarse correction of a stitched volume: the springs' Σ k n nᵀ at rest; their pull (no
  // anchors, no damping); pinned or held on the probe by the last step; positions += du on the
  // moving nodes, velocities kept (the probe-distance bounds are lowered by the move).
  Eigen::SparseMatrix<double, Eigen::RowMajor> rest_stiffness_mn_per_mm() const override;
  void tissue_forces_mn(Eigen::VectorXd& forces_mn) const override;
  bool holds_node(int node) const override { return !moves(node); }
  void displace_free_nodes_mm(const Eigen::VectorXd& du_mm) override;
  void move_held_node_mm(int node, const Eigen::Vector3d& position_mm) override;

  // The next frame (one step() or step_within()) integrates `frames` times the simulated time of
  // one: the implicit integrator in its implicit_steps_per_frame steps, each that many times as
  // long (stable at any step), the explicit one in that many times its steps. A stitched volume
  // whose frame has no time for all its seam exchanges covers it in fewer, longer parts.
  // Throws std::invalid_argument unless 1 <= frames <= 64.
  void stretch_next_frame(int frames);

  // Runs `steps` integration steps of `dt_s` (with the probe's contact) and nothing else: no
  // divergence check, no recovery. For measuring stability limits in tests and benches.
  void integrate_unchecked(const ProbeCollider* probe, double dt_s, int steps);

  // The explicit step's stability bound for this mesh and these settings, s:
  // forward_euler_stable_time_step_s(msds_max_omega_squared_bound(...), damping_per_stiffness_s).
  // Holds for the linearisation about rest. A spring at length l adds k(1 − L/l) sideways: pulled
  // long, a node with few springs across it (the 5-tet lattice's six-spring nodes) can pass the
  // bound (weigh_runaway_nodes); compressed below half its rest length, beyond k, negative.
  double explicit_stable_time_step_s() const;
  // Total free mass over the physical one: > 1 when scale_mass_for_explicit_step raised masses.
  double mass_scale() const { return mass_scale_; }

  // Spring, anchor and damping force on every node at the current state, mN, node-major x,y,z
  // (pinned nodes included: there it is what holds them). Resizes `forces_mn`; serial; for tests
  // and reports.
  void internal_forces_mn(Eigen::VectorXd& forces_mn) const;
  double kinetic_energy_uj() const;
  double elastic_energy_uj() const;
  // Kinetic energy no sane frame reaches: the elastic energy of every spring strained by 100%.
  double kinetic_energy_ceiling_uj() const { return kinetic_energy_ceiling_uj_; }
  int inverted_tet_count() const;

  std::span<const MsdsSpring> springs() const { return springs_; }
  std::span<const double> node_masses_kg() const { return mass_kg_; }
  std::span<const Eigen::Vector3d> velocities_mm_per_s() const { return v_; }
  const MsdsSettings& settings() const { return settings_; }
  MsdsIntegrator integrator() const { return integrator_; }
  int node_count() const { return static_cast<int>(rest_.size()); }

 private:
  struct StepResult {
    bool finite = true;
    double kinetic_energy_uj = 0.0;
    int cg_iterations = 0;
    double cg_relative_residual = 0.0;
  };
  struct AttemptResult {
    bool accepted = false;
    bool blew_up = false;  // non-finite or kinetic energy past the ceiling (not just inversion)
    DivergenceCause cause = DivergenceCause::kNone;  // why it was not accepted
    int inverted_tets = 0;
    int iterations = 0;  // integration steps (explicit) or CG iterations (implicit)
    double relative_residual = 0.0;
  };
  // Per-node 3-vectors, one array per coordinate (structure of arrays, for SIMD), each
  // msds_detail::kNodePadding past the last node (zero there).
  struct NodeVectors {
    std::vector<double> x, y, z;

    void assign_zero(int node_count);
    Eigen::Vector3d operator[](int node) const { return {x[node], y[node], z[node]}; }
    void set(int node, const Eigen::Vector3d& value);
    void copy_from(const NodeVectors& other);  // same size: no allocation
  };
  // The explicit step's float kernel and its scratch (msds.cpp).
  struct ExplicitKernel;

  // Setup (allocates).
  void build_springs(const geometry::TetMesh& mesh, std::span<const Material> tet_materials);
  void build_masses(const geometry::TetMesh& mesh);
  void scale_masses_to_time_step();
  void build_speed_ceilings();
  void build_adjacency();
  void size_buffers();
  void build_explicit_kernel();
  void build_contact_clusters();

  // One frame's pieces (no allocation).
  EngineStepStats run_frame(const ProbeCollider* probe);
  // step_within()'s budget during the frame (null outside it) and whether it stopped a CG.
  const StepBudget* budget_ = nullptr;
  bool cut_short_ = false;
  int next_frame_stretch_ = 1;  // stretch_next_frame's, for one frame
  AttemptResult run_attempt(const ProbeCollider* probe, double dt_s, int steps);
  int count_inverted_tets(const NodeVectors& at);  // inverted_tet_count() on the job system
  // Inverted tets in the frame's starting shape (what it may keep), counted once a frame when
  // first asked.
  int inverted_at_frame_start();
  bool outruns_its_springs(int node) const;  // past its speed_ceiling_squared_
  bool a_node_outruns_its_springs();         // any node, on the job system
  void weigh_runaway_nodes();                // mass scaled again for those nodes' stretched springs
  void recount_mass_scale();
  double stretched_gershgorin_row_mn_per_mm(int node) const;
  // One step: contacts, spring forces, then one node pass of the integrator (plus CG).
  // new_probe: the probe may differ from the last step's (the first step of a frame or a run):
  // query every node for contact, not only those that may have reached it.
  StepResult advance(const ProbeCollider* probe, double dt_s, bool new_probe);
  void clear_contacts();
  void apply_contacts(const ProbeCollider* probe, bool new_probe);
  // The free nodes that may be in contact (candidate_*, in node order), with fresh probe
  // clearances: every node for a new probe, else those whose bound reaches the probe.
  void collect_contact_candidates(const ProbeCollider& probe, bool new_probe);
  void query_every_cluster(const ProbeCollider& probe);
  void query_nodes_near_probe(const ProbeCollider& probe);
  // Queries one node: its clearance, and whether it is a candidate.
  void query_node(const ProbeCollider& probe, int node);
  // Each node block's least clearance (block_min_clearance_mm_), from the nodes'.
  void update_block_min_clearances();
  void release_if_pulled_away(int node, const Eigen::Vector3d& force_mn);
  // HeldContactModel::kCoulombSlip: a held node slides along the probe (slide_held_node).
  void slide_along_probe(const ProbeCollider& probe, NodeContact& contact);
  // The springs' and the anchor's elastic force on the node (as gather_node_forces) and the
  // node's own block of their stiffness, in one pass over its springs.
  void elastic_force_and_stiffness(int node, Eigen::Vector3d& elastic_mn,
                                   Eigen::Matrix3d& stiffness_mn_per_mm) const;
  // Every spring's elastic and damping force at the current state and its implicit block
  // (implicit_lattice_), on the job system.
  void compute_spring_forces(double dt_s);
  StepResult explicit_euler_update(double dt_s);
  // The explicit step on one task's run of node blocks.
  void explicit_euler_task(int task, double dt_s);
  // The contacts among nodes [begin, end), given their float spring forces: let go those pulled
  // away (release_if_pulled_away); zero the force of those still held, which do not move.
  void settle_contacts(int begin, int end, float* force_x, float* force_y, float* force_z);
  StepResult implicit_euler_update(double dt_s);
  // q = (M + h C + h² K) p on the job system (system_diagonal_ = M + the anchors' h² k). For a
  // CG iteration (`pq`), zero on the nodes that do not move and each node chunk's p · q in
  // partial_a_; else every node's row (a held node the step then releases needs its own).
  void system_times(const NodeVectors& p, NodeVectors& q, bool pq);
  // x += h v1; v1 is kept as the velocity unless the budget truncated the CG (then zero).
  StepResult finish_implicit_update(double dt_s, bool truncated);
  double contact_force_n() const;
  int held_node_count() const;
  void reset_to_rest();
  // The float copy of the state the explicit kernel reads (after any change outside its pass).
  void sync_float_state();
  // Refreshes the public views of the state: x_, v_ and u_.
  void publish_state();

  // The anchor's elastic and damping force on a node (zero without one), at the current state.
  void anchor_force(int node, Eigen::Vector3d& elastic_mn, Eigen::Vector3d& damping_mn) const;
  void anchor_force(const AnchorSpring& anchor, Eigen::Vector3d& elastic_mn,
                    Eigen::Vector3d& damping_mn) const;
  // Adds the anchors' forces on nodes [begin, end) to the explicit pass's float block forces.
  void add_anchor_forces(int begin, int end, float* force_x, float* force_y, float* force_z) const;
  // Explicit Euler with mass scaling: a node's mass for its springs' and anchor's stiffness.
  void rescale_anchored_mass(int node, double anchor_stiffness_mn_per_mm);
  // Spring (+ anchor) + damping force on one node, at the current state (computed afresh).
  void gather_node_forces(int node, Eigen::Vector3d& elastic_mn, Eigen::Vector3d& damping_mn) const;
  // Unit vector from node `from` to the spring's other node (the rest direction if collapsed),
  // and the spring's current length.
  Eigen::Vector3d spring_direction(int from, int to, double rest_length_mm,
                                   double& length_mm) const;
  bool moves(int node) const { return pinned_[node] == 0 && held_[node] == 0; }

  // Runs body(chunk) for chunk in [0, count): inside step() and integrate_unchecked() on the
  // job system's threads (one JobSystem::run() per call, msds_task_team.hpp), else inline.
  template <typename Body>
  void for_each_chunk(int count, Body&& body);
  // Σ of the first `chunks` partial sums, in chunk order (identical with and without jobs).
  double sum_partials(const std::vector<double>& partials, int chunks) const;
  // The kinetic energy and finiteness an update pass left in the node chunks' partials.
  StepResult gather_update_result() const;
  int node_chunk_count() const;

  MsdsIntegrator integrator_;
  MsdsSettings settings_;
  hal::JobSystem* jobs_ = nullptr;
  std::unique_ptr<msds_detail::TaskTeam> team_;
  std::vector<Eigen::Vector3d> rest_;
  std::vector<geometry::Tet> tets_;
  // Fixed, or in no tet (no mass): never moves. kNodePadding past the last node (pinned there).
  std::vector<std::uint8_t> pinned_;
  std::vector<MsdsSpring> springs_;
  std::vector<double> mass_kg_;              // node_count entries (the public view)
  std::vector<double> padded_mass_kg_;       // kNodePadding past the last node (zero there)
  std::vector<double> inverse_mass_per_kg_;  // likewise; 0 on pinned nodes
  double kinetic_energy_ceiling_uj_ = 0.0;
  // Each node's: the square of the speed at which its kinetic energy equals its springs' energy
  // at 100 % strain, mm²/s² (infinite on pinned nodes).
  std::vector<double> speed_ceiling_squared_;
  double mass_scale_ = 1.0;
  // Mass scaling's inputs, kept for anchored nodes: physical masses, each node's Gershgorin row
  // sum of its springs (mN/mm; a runaway node's as stretched when it was weighed), the largest ω²
  // the step is stable for (empty / 0 without scaling).
  std::vector<double> physical_mass_kg_;
  std::vector<double> gershgorin_row_mn_per_mm_;
  double stable_omega_squared_ = 0.0;
  // Anchor springs in node order, and per node its anchor's stiffness (0: none) and the stiffness
  // its mass was last scaled for.
  std::vector<AnchorSpring> anchors_;
  std::vector<double> anchor_stiffness_mn_per_mm_;
  std::vector<int> anchor_of_node_;  // index in anchors_, −1: none
  std::vector<double> mass_scaled_for_anchor_mn_per_mm_;
  // Node → springs (CSR), each entry with the spring's other node, in spring order.
  std::vector<int> adjacency_begin_;
  std::vector<int> adjacency_spring_;
  std::vector<int> adjacency_other_;

  // State.
  NodeVectors position_;  // deformed positions, mm
  NodeVectors velocity_;  // mm/s
  // Public views, refreshed at the end of every step and state change (publish_state).
  std::vector<Eigen::Vector3d> x_;  // positions, mm
  std::vector<Eigen::Vector3d> v_;  // velocities, mm/s
  Eigen::VectorXd u_;               // x − rest, node-major

  // Per-step and per-frame scratch, sized once.
  NodeVectors position_frame_start_, velocity_frame_start_;
  int inverted_at_frame_start_ = -1;         // -1: not counted this frame
  std::vector<NodeContact> contacts_;        // in node order
  std::vector<std::uint8_t> held_;           // contact held on the probe surface this step (padded)
  std::vector<std::uint8_t> touching_only_;  // contact on the surface, not inside: may be let go
  std::vector<std::uint8_t> on_surface_;     // on the mesh's boundary: may slide along the probe
  std::vector<Eigen::Vector3d> contact_normal_;  // the probe's outward normal at a contact
  // A lower bound of each node's signed distance to the probe (mm, padded); see
  // msds_detail::ExplicitNodeArrays.
  std::vector<double> probe_clearance_mm_;
  std::vector<double> block_min_clearance_mm_;  // per node chunk, the least of those
  std::vector<int> candidate_nodes_;            // may be in contact this step, in node order
  std::vector<Eigen::Vector3d> candidate_positions_mm_;
  std::vector<std::uint8_t> candidate_fixed_;  // all 0: candidates are free nodes
  // Free nodes grouped by spatial cells of a few nodes (CSR), each cell's centre at rest: a new
  // probe is queried once per cluster, and node by node only in clusters that may reach it.
  std::vector<int> cluster_begin_;
  std::vector<int> cluster_nodes_;
  std::vector<Eigen::Vector3d> cluster_center_mm_;
  std::unique_ptr<ExplicitKernel> explicit_;              // explicit integrator only
  std::unique_ptr<msds_detail::TetLattice> tet_lattice_;  // the inversion count's layout
  // Implicit Euler: the springs' elastic forces and blocks by diagonal, each node's sums of them
  // (node_*), its diagonal M + h² k_anchor (system_diagonal_), the system's inverse diagonal and
  // the CG's vectors (cg_velocity_: the new velocity being solved for), by coordinate (SIMD).
  std::unique_ptr<msds_detail::ImplicitLattice> implicit_lattice_;
  NodeVectors node_elastic_, node_block_diagonal_;
  std::vector<double> system_diagonal_;
  NodeVectors inverse_diagonal_, rhs_, r_, z_, p_, q_, cg_velocity_;
  std::vector<double> partial_a_, partial_b_, partial_c_, partial_d_, partial_e_;
  std::vector<std::uint8_t> partial_finite_, partial_runaway_;
  // The last implicit step's CG was stopped by the budget: its unfinished velocity (still in
  // cg_velocity_) is the next step's CG start where it lowers that step's energy
  // (implicit_euler_update), though not its momentum. False after anything that moves the
  // state otherwise (a kept or reset frame, set_displacements_mm).
  bool truncated_velocity_kept_ = false;
};

}  // namespace ultrasim::sim
