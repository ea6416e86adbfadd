#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/coarse_correction.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/fine_correction.hpp"
#include "ultrasim/sim/settings.hpp"
#include "ultrasim/sim/sub_volume_split.hpp"

namespace ultrasim::sim {

class CorotationalFem;
class MsdsEngine;
class StitchedFrameTime;

// Whether a method can run stitched: it takes anchor springs (the MSDS, the PCG and corotational
// FEMs).
bool stitchable(EngineKind method);

// What a stitched frame did, beyond the engine's stats.
struct StitchStepStats {
  int sub_volumes_stepped = 0;
  int sub_volumes_touched = 0;   // within the probe's reach (always stepped)
  int sub_volumes_asleep = 0;    // after the frame
  int sub_volumes_deferred = 0;  // due but left for a later frame (selection or budget)
  // Seam exchanges the frame ran, and those of the method's it had no time for (step_sharing:
  // their least work did not fit).
  int exchanges = 0;
  int exchanges_left_out = 0;
  // Corotational sub-volumes' due updates of the warped system held for want of time
  // ([stitching] corotational_update_turns_held), over the frame's exchanges.
  int updates_held = 0;
  double max_seam_force_mn = 0.0;  // largest zero-length spring force after the frame
  double max_gap_mm = 0.0;         // largest distance between copies of a shared node
  // The coarse correction's largest nodal move this frame, mm (0: off or nothing to correct),
  // and the sub-volumes it moved (those not stepped among them are woken).
  double coarse_move_mm = 0.0;
  int sub_volumes_corrected = 0;
  // The fine correction's iterations this frame and its largest nodal move, mm (0: off).
  int fine_iterations = 0;
  double fine_move_mm = 0.0;
};

// Volume stitching (published ch. 5): a region meshed as one grid, split into overlapping
// sub-volumes (split_grid), each simulated by its own engine of any method that takes anchor
// springs (MSDS explicit or implicit, PCG FEM). The copies of a shared node are joined by
// zero-length springs of stiffness k, acting on each copy as one anchor spring: stiffness
// k × (copies − 1) toward the mean of the other copies, the same force as the pairwise springs.
// A frame alternates as published: every stepped sub-volume first takes its anchors from the
// others' current positions (all at once, so the sub-volumes step in parallel on the job system,
// one sub-volume per task), then steps. The copies of a shared node that the probe holds in
// several sub-volumes (each where its own contact caught it) are then put at their mean, where the
// next step's contact takes them up alike: a node has one place on the probe. With [stitching]
// coarse_correction, a coarse-grid step over the whole region follows (CoarseCorrection). The
// region shows each shared node at the mean of its copies (the published midpoint fix), so no gap
// shows; the gap before that is reported.
//
// As a DeformationEngine it is one engine on the whole grid's mesh: positions, displacements and
// the live switch are on the grid's nodes. Units as the engines'. The frame thread owns it; step()
// does not allocate once warmed up.
class StitchedVolume final : public DeformationEngine {
 public:
  // The region: the grid (meshed with make_grid_tet_mesh), a material per grid tet, fixed-node
  // flags per grid node. `jobs`, if given, must outlive the volume. Throws std::invalid_argument
  // for a split that does not fit, a method that cannot take anchor springs, or the engines'
  // own reasons (a sub-volume with no fixed node, for one: each must be held somewhere).
  StitchedVolume(const geometry::GridSpec& grid, std::span<const Material> tet_materials,
                 std::span<const std::uint8_t> fixed_nodes, EngineKind method,
                 const EngineSettings& engine_settings, const StitchingSettings& stitching,
                 hal::JobSystem* jobs = nullptr);
  ~StitchedVolume() override;
  StitchedVolume(const StitchedVolume&) = delete;
  StitchedVolume& operator=(const StitchedVolume&) = delete;

  EngineKind kind() const override { return method_; }
  std::string_view name() const override { return name_; }
  // A frame of every due sub-volume; see step_within().
  EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) override;
  // The same, in priority order: the sub-volumes the probe may touch (always), then the rest due
  // this frame, those pulled hardest by their seams first, in batches of one per job thread
  // (paired to share the fewest seam nodes) while may_continue() says there is time (an empty
  // function: no limit); which sub-volumes step is decided in the first of the frame's exchanges,
  // and the later ones step the same (without the time left, step_sharing(), the first exchange
  // may take it all and the later ones run their least work). Each sub-volume's own step takes
  // it too, in every exchange, as one piece's does (the CG methods stop iterating, one iteration at
  // least; the explicit MSDS stops stepping and retrying): it is asked from the job system's
  // threads, one at a time. Stats: the sum of the sub-volumes' iterations, contact nodes and
  // contact forces' magnitudes, the most inverted tets of one, diverged if any did, and the
  // strongest recovery; cut_short when a due sub-volume was left for later or a stepped one's own
  // step was cut short.
  EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                              const StepBudget& may_continue) override;
  // The time left for the budgeted work, µs, from the caller's clock (the library reads none);
  // asked from the job system's threads, one at a time.
  using TimeLeftUs = std::function<std::int64_t()>;
  // step_within(), knowing the time left: the time (less what the work after the steps took last
  // frame) is shared evenly over the frame's exchanges and, within each, over the touched
  // sub-volumes' batches and as many of the other due ones as fit at last frame's least batch
  // work (up to its first question and what followed its "no"); each batch stops its own work
  // once its share is spent, and a batch beyond those planned starts only if its least work in
  // every exchange still ends in time. (Without it the first touched batch's CG took the whole
  // share, each later batch ran its fixed work and one iteration past the deadline, and no
  // neighbour of the touched sub-volumes stepped.) The frame runs as many of exchanges_per_frame
  // exchanges as its touched batches' least work fits (a divisor of it, one at least), each
  // covering that many more of the frame's time (an MSDS sub-volume integrates it in its
  // implicit steps made longer, or in more explicit ones: MsdsEngine::stretch_next_frame). An
  // empty time_left_us: exactly step_within().
  EngineStepStats step_sharing(const ProbeCollider* probe, double frame_dt_s,
                               const StepBudget& may_continue, const TimeLeftUs& time_left_us);
  const Eigen::VectorXd& displacements_mm() const override { return u_; }
  std::span<const Eigen::Vector3d> deformed_positions_mm() const override { return shown_; }
  // Every sub-volume continues from the grid's field (copies of a shared node alike), awake.
  void set_displacements_mm(const Eigen::VectorXd& u_mm) override;

  const StitchStepStats& last_stitch_stats() const { return stats_; }
  // This method's: StitchingSettings::exchanges_per_frame, explicit_msds_exchanges_per_frame,
  // implicit_msds_exchanges_per_frame or corotational_exchanges_per_frame.
  int exchanges_per_frame() const { return exchanges_per_frame_; }
  const geometry::TetMesh& mesh() const { return mesh_; }
  int sub_volume_count() const { return static_cast<int>(subs_.size()); }
  const SubVolumeBox& box(int sub) const { return subs_[sub].box; }
  const DeformationEngine& sub_volume_engine(int sub) const { return *subs_[sub].engine; }
  bool asleep(int sub) const { return subs_[sub].asleep; }
  // Whether the last frame stepped the sub-volume, and its step's stats.
  bool stepped(int sub) const { return subs_[sub].stepped; }
  const EngineStepStats& last_step_stats(int sub) const { return subs_[sub].last_stats; }
  // Whether the probe could reach the sub-volume in the last frame (it stepped whatever the time).
  bool touched(int sub) const { return subs_[sub].touched; }
  // The sub-volumes the last frame stepped, in the order they stepped: one batch of as many as
  // the job system has threads after another.
  std::span<const int> step_order() const {
    return std::span(schedule_).first(static_cast<std::size_t>(stats_.sub_volumes_stepped));
  }

 private:
  struct SubVolume {
    SubVolumeBox box;
    std::unique_ptr<DeformationEngine> engine;
    CorotationalFem* corotational = nullptr;  // the engine, if it is one (its update clock)
    MsdsEngine* msds = nullptr;               // the engine, if it is one (its frame's length)
    std::vector<int> global_node;             // per local node
    // Shared local nodes (in node order) and, per entry, its copy's index in copies_.
    std::vector<int> shared_local;
    std::vector<int> shared_copy;
    std::vector<AnchorSpring> anchors;  // one per free shared node, refreshed before a step
    std::vector<Eigen::Vector3d> previous_positions_mm;
    // 3 × local nodes, sized once: a refused frame's displacements (place_sub_volumes' scratch).
    Eigen::VectorXd revert_mm;
    Eigen::VectorXd cut_back_mm;  // 3 × local nodes: a frame cut back along its update
    // The engine's deformed positions (refreshed whenever it changes them).
    std::span<const Eigen::Vector3d> positions_mm;
    // Blocks of a few nodes per axis (per local node, its block; per block, its local nodes from
    // block_node_start[b]) and each block's bounding box at the last step: the probe's reach is
    // tested per block, then per node of a block it may reach, so a probe near a sub-volume's
    // edge does not count as touching it.
    std::vector<int> node_block;
    std::vector<int> block_node_start, block_nodes;
    std::vector<Eigen::Vector3d> block_center_mm;
    std::vector<double> block_half_diagonal_mm;
    std::vector<Eigen::AlignedBox3d> block_bounds;
    std::vector<std::uint8_t> block_near_probe;  // per block, refreshed with the anchors
    double max_seam_force_mn = 0.0;
    double max_seam_gap_mm = 0.0;
    double last_motion_mm = 0.0;
    int frames_waiting = 0;  // since it last stepped
    // Times it waited for the time its update needs since its last update (step_sharing).
    int times_update_waited = 0;
    bool asleep = false;
    bool stepped = false;
    bool touched = false;
    bool moved = false;  // this frame: stepped, or moved by a correction or a join
    EngineStepStats last_stats;
  };
  // Beyond the probe's surface by this much a node is not in contact (the engines' contact
  // tolerances are far smaller): a sub-volume whose every node is farther is out of reach.
  static constexpr double kReachMarginMm = 0.5;
  // A copy of a grid node: the sub-volume and its local node.
  struct Copy {
    int sub = 0;
    int local = 0;
  };

  void build_sub_volumes(std::span<const Material> tet_materials,
                         std::span<const std::uint8_t> fixed_nodes, EngineKind method,
                         const EngineSettings& engine_settings, hal::JobSystem* jobs);
  void build_copies(std::span<const Material> tet_materials);
  // The order this frame's sub-volumes step in (schedule_), those that must step first (the
  // touched ones and those a torn seam left standing, step_next_); returns how many must.
  int plan_frame(const ProbeCollider* probe);
  // Reorders schedule_'s first `due` entries (the first `touched` of them must step: in the
  // probe's reach or left standing by a torn seam) into batches of `batch` (one per thread)
  // whose sub-volumes share the fewest seam nodes; returns how many of its first entries must
  // step: through the last batch that holds one that must.
  int order_into_batches(int touched, int due, int batch);
  // Order among the due sub-volumes not touched: seam pull × (1 + frames waited).
  double priority(int sub) const;
  // Each shared node's anchor: k × (copies − 1) toward the other copies' mean, or, in a sub-volume
  // the probe may touch, toward where the probe pushes that mean out to if it lies inside it.
  void refresh_anchors(int sub, const ProbeCollider* probe);
  // Whether the probe may touch a node of the sub-volume (its blocks' bounds at the last step).
  bool within_reach(const SubVolume& sub, const ProbeCollider& probe) const;
  // One part of a frame for each of `subs`, anchors first, covering `stretch` of the method's
  // exchanges' time; `first_part`: the frame's first
  // exchange (it keeps the positions the frame started from and starts the frame's stats).
  // `budget` is each sub-volume's own (step_within; thread-safe: the batch steps in parallel).
  void step_batch(std::span<const int> subs, const ProbeCollider* probe, double frame_dt_s,
                  int stretch, bool first_part, const StepBudget& budget, bool hold_updates);
  // What a seam update does with the loads its copies carry: an accepted frame remembers, a
  // cut-back one, or one refused for want of time with nothing in the probe's reach, halves
  // those of its seams, any other update (a refusal under the probe, construction, a region put
  // to rest, whose loads are zero) keeps them.
  enum class SeamLoads { kKeep, kRemember, kHalve };
  // Per shared node: gap and seam forces (and loads); per sub-volume: seam force, bounds, sleep.
  // Then the shown positions (copies' mean) and displacements.
  void finish_frame(SeamLoads loads);
  // The coarse correction's share of the residual of the sub-volumes that stepped.
  void update_coarse_residuals(std::span<const int> stepped);
  // The fine correction over the sub-volumes that stepped, after their steps (may_continue: the
  // frame's budget, as for the steps).
  void correct_finely(const StepBudget& may_continue);
  // The frame's verdict on the sub-volumes it stepped (`in_reach`: how many the probe may touch;
  // `deferred`: a due one was left for later): refused and reverted, cut back along its update,
  // the region put to rest (refused with nothing in reach, not for want of time), or kept (the
  // held copies joined, the fine correction); then the coarse residuals, the seams and shown
  // positions (finish_frame). Returns the frame's stats as one engine's.
  EngineStepStats settle_frame(std::span<const int> stepped, int in_reach, bool deferred,
                               const StepBudget& may_continue);
  // The stepped sub-volumes' stats as one engine's: work and contact summed, the worst of the
  // rest.
  EngineStepStats stepped_stats() const;
  // Whether the frame must be refused as a whole: a sub-volume refused its part or was reset.
  // Accepting the rest would leave that sub-volume at its frame's start, or at rest, against
  // neighbours pressed on: the seam tears, its springs pull the copies apart harder each frame,
  // and the explicit MSDS blew up (the soak with the large case: 13 resets in 60 s, a 2.2 m gap).
  // Each sub-volume's verdict is its method's own rule on its part (inverted tets over the
  // method's fraction of its tets, less what the method exempts: the corotational FEM's tets
  // pressed flat between probe contacts, a folded shape it was handed unfolding); their inverted
  // tets are not summed against one piece's limit, which refused what every part accepted, again
  // every frame while the probe stayed.
  // A frame is refused too when it opened a seam wider than [stitching] refuse_gap_mm (and wider
  // than it was): a torn seam. `cause` says which.
  bool refuses_frame(std::span<const int> stepped, DivergenceCause& cause);
  // Whether a seam of a `stepped` sub-volume is now wider than refuse_gap_mm and than last frame;
  // with mark_standing, marks in step_next_ the sub-volumes that did not step holding a copy of
  // a torn seam's node.
  bool tears_a_seam(std::span<const int> stepped, bool mark_standing);
  // Every stepped sub-volume back to where the frame found it (at rest velocity).
  void revert_frame(std::span<const int> stepped);
  // Every sub-volume to the grid's field *u_mm (rest where null; copies of a shared node alike),
  // at rest velocity, awake (finish_frame may put it to sleep), marked moved, its seams carrying
  // no load.
  void place_sub_volumes(const Eigen::VectorXd* u_mm);
  // The displacements the frame found the sub-volume at, into its revert_mm.
  void frame_start_displacements(SubVolume& sub);
  // Every stepped sub-volume to half, a quarter, ... (to 1/256) of the way from where the frame
  // found it to where it stepped (at rest velocity), the first that tears no seam; false (and
  // left at 1/256) if none.
  bool cut_back_frame(std::span<const int> stepped);
  // The copies of a seam node that the probe holds in several sub-volumes, each where it caught
  // its copy, to their mean: the next step's contact test takes them up in one place.
  void join_held_copies();
  void join_held_copies_of(int grid_node);
  // The first of grid node g's copies (in sub-volume order) whose sub-volume moved this frame, or
  // -1: the one whose finish_frame task updates the seam.
  int first_moved_copy(int g) const;
  // A shared node's midpoint, gap, loads and pull from its copies.
  void update_seam(int grid_node, SeamLoads loads);
  // visit(g) once for each grid node that a moved sub-volume (`moved` as the loop reaches it)
  // shares at a local node keep(sub, local) accepts.
  template <typename Keep, typename Visit>
  void for_each_moved_seam_node(Keep keep, Visit visit);
  // The coarse step, at a frame's start; moves (and wakes) every sub-volume it asks to move by
  // more than the sleep motion. Block bounds are refreshed at the frame's end: until then the
  // reach test widens by the move.
  void correct_coarsely();
  // The sub-volume's positions from its engine (positions_mm) and its seam copies' into
  // copy_positions_mm_: after anything that moves its nodes.
  void take_positions(SubVolume& sub);
  // The largest distance between two of grid node g's copies (the seam's gap there).
  double widest_copy_gap_mm(int g) const;
  // Σ of the positions of grid node g's copies.
  Eigen::Vector3d copies_sum(int g) const;

  geometry::GridSpec grid_;
  geometry::TetMesh mesh_;
  EngineKind method_;
  std::string name_;
  StitchingSettings settings_;
  // The frame's budget is one clock: the sub-volumes stepping in parallel ask it in turn.
  std::mutex budget_mutex_;
  hal::JobSystem* jobs_ = nullptr;
  std::vector<SubVolume> subs_;
  // Per grid node, its copies (CSR; none listed for a node of one sub-volume alone), and the
  // seam spring's stiffness there (0 if not shared).
  std::vector<int> copies_begin_;
  std::vector<Copy> copies_;
  std::vector<double> seam_stiffness_mn_per_mm_;
  std::vector<int> shared_nodes_;  // grid nodes with more than one copy
  int exchanges_per_frame_ = 1;
  // Seam exchanges so far (a frame's parts each count): the corotational sub-volumes' update
  // clock, so that neighbours update in turn whichever of them step.
  std::int64_t exchange_count_ = 0;
  // Per pair of sub-volumes (s × count + t), the grid nodes both hold (0 on the diagonal).
  std::vector<int> shared_node_count_;
  std::vector<std::uint8_t> fixed_;
  std::unique_ptr<CoarseCorrection> coarse_;  // null: off
  std::vector<int> corrected_;                // per frame, sized once
  std::unique_ptr<FineCorrection> fine_;      // null: off
  std::vector<DeformationEngine*> engines_;   // per sub-volume, for the fine correction
  std::vector<std::uint8_t> stepped_flags_;   // per frame, sized once

  // Per frame, sized once.
  std::vector<int> schedule_;
  std::vector<int> batched_;
  std::vector<std::uint8_t> placed_;
  std::vector<std::uint8_t> due_;
  // Per sub-volume: a corotational one whose update this frame cannot be held (update_forced_at).
  std::vector<std::uint8_t> update_forced_;
  // Per sub-volume: holds a copy of a seam node the last frame tore without stepping it; it
  // steps in the next frame whatever the time.
  std::vector<std::uint8_t> step_next_;
  std::vector<Eigen::Vector3d> shown_;
  // Per grid node: the widest gap between its copies and the strongest pull on one, as of the
  // last frame any of its copies moved (0 where not shared); and a stamp, so that a loop over
  // sub-volumes' seam nodes visits each grid node once (for_each_moved_seam_node).
  std::vector<double> seam_gap_mm_;
  std::vector<double> seam_force_mn_;
  // Per copy (as copies_), the load its seam carried so far, mN ([stitching] seam_load_rate;
  // zero when 0); they add up to zero over a node's copies. And the springs' pull on it when its
  // seam was last updated (a seam none of whose copies moved pulls the same).
  std::vector<Eigen::Vector3d> seam_load_mn_;
  std::vector<Eigen::Vector3d> seam_pull_before_mn_;
  // The implicit MSDS's seam lead (StitchingSettings::implicit_msds_seam_lead; 0 for the other
  // methods). Per grid node, its copies' mean's move in one exchange over the last frame that
  // kept a step of every copy (its exchanges: stats_.exchanges), and that frame's number
  // (frames_finished_ counts finish_frame's calls: a move not from the latest is not led by).
  double seam_lead_ = 0.0;
  std::vector<Eigen::Vector3d> seam_move_per_exchange_mm_;
  std::vector<Eigen::Vector3d> seam_move_before_mm_;
  std::vector<std::uint32_t> seam_move_frame_;
  std::uint32_t frames_finished_ = 0;
  // Per sub-volume: it steps in the current exchange and has yet to (a twin's anchor leads it).
  std::vector<std::uint8_t> steps_later_in_exchange_;
  std::vector<std::uint32_t> node_stamp_;
  std::uint32_t node_stamp_counter_ = 0;
  std::vector<int> moved_subs_;                   // per frame, sized once
  std::vector<std::uint8_t> holds_updated_seam_;  // per sub-volume, per frame, sized once
  // tears_a_seam's, sized once: the stepped sub-volumes whose seams it looks at node by node;
  // per sub-volume, its seam copies' largest move this frame and whether it tears a seam.
  std::vector<int> subs_to_look_at_;
  std::vector<double> seam_move_mm_;
  std::vector<std::uint8_t> tears_seam_;
  // Per copy (as copies_), its position (take_positions): a seam node's copies side by side for
  // the anchors, the seams' update and the tear check (read from each sub-volume's own
  // positions, the copies of a node lie apart and each read missed the cache: a third of the
  // seams' update).
  std::vector<Eigen::Vector3d> copy_positions_mm_;
  Eigen::VectorXd u_;
  StitchStepStats stats_;
  // The frame's time shared over its exchanges and batches, and what they cost (step_sharing).
  std::unique_ptr<StitchedFrameTime> frame_time_;
};

}  // namespace ultrasim::sim
