#include "ultrasim/sim/stitched_volume.hpp"

#include <algorithm>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>

#include "ultrasim/sim/corotational_fem.hpp"

namespace ultrasim::sim {

namespace {

std::string sub_name(const SubVolumeBox& box) {
  return "sub-volume (" + std::to_string(box.index.x()) + ", " + std::to_string(box.index.y()) +
         ", " + std::to_string(box.index.z()) + ")";
}

// Beyond the probe's surface by this much a node is not in contact (the engines' contact
// tolerances are far smaller): a sub-volume whose every node is farther is out of reach.
constexpr double kReachMarginMm = 0.5;
// Copies of a seam node the probe holds in several sub-volumes farther apart than this (issue 5's
// gap target) are put at their mean.
constexpr double kJoinHeldCopiesMm = 0.1;
// A seam's remembered loads fade by this fraction a frame where its copies did not all step
// ([stitching] seam_load_rate).
constexpr double kSeamLoadFadePerFrame = 0.1;
// A corotational sub-volume out of the probe's reach whose update cannot be held waits for a
// frame with the time for it at most this many times between two updates (with an update due
// every other frame, four seconds; between its due frames it may step and solve the last warped
// system). At 60 the seam presses' neighbours took their update whatever the time within a
// press and hold of 2.2 s, and the simulation's p99 rose from 5.2-5.3 to 5.3-6.2 ms (at 120:
// 5.3-5.5 ms).
constexpr int kMostTimesAnUpdateWaits = 120;
// Nodes per axis of the blocks the reach test bounds (4³ = 64 nodes, a few mm across).
constexpr int kReachBlockNodes = 4;

}  // namespace

// The widest distance between any two of `count` points (position(i)).
template <typename Position>
double widest_gap_mm(int count, Position position) {
  double gap = 0.0;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d x = position(i);
    for (int j = i + 1; j < count; ++j) gap = std::max(gap, (position(j) - x).norm());
  }
  return gap;
}

bool stitchable(EngineKind method) {
  return method == EngineKind::kPcgFem || method == EngineKind::kCorotationalFem ||
         method == EngineKind::kMsdsExplicit || method == EngineKind::kMsdsImplicit;
}

StitchedVolume::StitchedVolume(const geometry::GridSpec& grid,
                               std::span<const Material> tet_materials,
                               std::span<const std::uint8_t> fixed_nodes, EngineKind method,
                               const EngineSettings& engine_settings,
                               const StitchingSettings& stitching, hal::JobSystem* jobs)
    : grid_(grid),
      mesh_(geometry::make_grid_tet_mesh(grid)),
      method_(method),
      settings_(stitching),
      jobs_(jobs),
      fixed_(fixed_nodes.begin(), fixed_nodes.end()) {
  if (static_cast<int>(tet_materials.size()) != mesh_.tet_count()) {
    throw std::invalid_argument("StitchedVolume: " + std::to_string(tet_materials.size()) +
                                " materials for " + std::to_string(mesh_.tet_count()) + " tets");
  }
  if (static_cast<int>(fixed_nodes.size()) != mesh_.node_count()) {
    throw std::invalid_argument("StitchedVolume: " + std::to_string(fixed_nodes.size()) +
                                " fixed flags for " + std::to_string(mesh_.node_count()) +
                                " nodes");
  }
  if (!(stitching.spring_stiffness_per_modulus_mm > 0.0)) {
    throw std::invalid_argument("StitchedVolume: spring_stiffness_per_modulus_mm must be > 0");
  }
  if (!(stitching.refuse_gap_mm > 0.0)) {
    throw std::invalid_argument("StitchedVolume: refuse_gap_mm must be > 0");
  }
  if (stitching.extra_sub_volumes_per_frame < 0) {
    throw std::invalid_argument("StitchedVolume: extra_sub_volumes_per_frame must be >= 0");
  }
  if (stitching.exchanges_per_frame < 1 || stitching.corotational_exchanges_per_frame < 1) {
    throw std::invalid_argument(
        "StitchedVolume: exchanges_per_frame and corotational_exchanges_per_frame must be >= 1");
  }
  if (stitching.corotational_turn_check_interval_frames < 1 ||
      stitching.corotational_rotation_update_interval_frames < 1) {
    throw std::invalid_argument(
        "StitchedVolume: corotational_turn_check_interval_frames and "
        "corotational_rotation_update_interval_frames must be >= 1");
  }
  if (stitching.corotational_update_turns_held < 0) {
    throw std::invalid_argument("StitchedVolume: corotational_update_turns_held must be >= 0");
  }
  if (stitching.msds_exchanges_per_frame < 1 ||
      engine_settings.msds.steps_per_frame % stitching.msds_exchanges_per_frame != 0) {
    throw std::invalid_argument("StitchedVolume: msds_exchanges_per_frame (" +
                                std::to_string(stitching.msds_exchanges_per_frame) +
                                ") must be >= 1 and divide the MSDS's steps_per_frame (" +
                                std::to_string(engine_settings.msds.steps_per_frame) + ")");
  }
  const bool msds = method == EngineKind::kMsdsExplicit || method == EngineKind::kMsdsImplicit;
  exchanges_per_frame_ = msds ? stitching.msds_exchanges_per_frame
                         : method == EngineKind::kCorotationalFem
                             ? stitching.corotational_exchanges_per_frame
                             : stitching.exchanges_per_frame;
  build_sub_volumes(tet_materials, fixed_nodes, method, engine_settings, jobs);
  build_copies(tet_materials);
  if (settings_.coarse_correction) {
    std::vector<SubVolumeBox> boxes;
    std::vector<const DeformationEngine*> engines;
    for (const auto& sub : subs_) {
      boxes.push_back(sub.box);
      engines.push_back(sub.engine.get());
    }
    coarse_ = std::make_unique<CoarseCorrection>(grid_, boxes, engines);
    corrected_.reserve(subs_.size());
  }
  if (settings_.fine_correction_iterations > 0) {
    std::vector<std::vector<int>> grid_nodes;
    std::vector<const DeformationEngine*> engines;
    for (const auto& sub : subs_) {
      grid_nodes.push_back(sub.global_node);
      engines.push_back(sub.engine.get());
      engines_.push_back(sub.engine.get());
    }
    fine_ = std::make_unique<FineCorrection>(grid_nodes, engines, fixed_);
    stepped_flags_.assign(subs_.size(), 0);
  }
  name_ = "stitched " + std::string(subs_.front().engine->name()) + " (" +
          std::to_string(subs_.size()) + " sub-volumes)";
  schedule_.reserve(subs_.size());
  batched_.reserve(subs_.size());
  placed_.assign(subs_.size(), 0);
  due_.assign(subs_.size(), 0);
  update_forced_.assign(subs_.size(), 0);
  tears_seam_.assign(subs_.size(), 0);
  seam_move_mm_.assign(subs_.size(), 0.0);
  step_next_.assign(subs_.size(), 0);
  shown_ = mesh_.rest_positions_mm;
  u_ = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(mesh_.node_count()));
  seam_gap_mm_.assign(mesh_.node_count(), 0.0);
  seam_force_mn_.assign(mesh_.node_count(), 0.0);
  seam_load_mn_.assign(copies_.size(), Eigen::Vector3d::Zero());
  seam_pull_before_mn_.assign(copies_.size(), Eigen::Vector3d::Zero());
  node_stamp_.assign(mesh_.node_count(), 0u);
  moved_subs_.reserve(subs_.size());
  subs_to_look_at_.reserve(subs_.size());
  seams_to_update_.reserve(shared_nodes_.size());
  holds_updated_seam_.assign(subs_.size(), 0);
  copy_positions_mm_.resize(copies_.size());
  for (std::size_t c = 0; c < copies_.size(); ++c) {
    copy_positions_mm_[c] = subs_[copies_[c].sub].positions_mm[copies_[c].local];
  }
  for (const int g : shared_nodes_) update_seam(g, SeamLoads::kKeep);  // fixed midpoints, once
  for (auto& sub : subs_) {
    sub.stepped = sub.moved = true;  // the first frame's bounds come from the rest shape
  }
  finish_frame(SeamLoads::kKeep);
  for (auto& sub : subs_) sub.stepped = sub.moved = false;
}

StitchedVolume::~StitchedVolume() = default;

void StitchedVolume::build_sub_volumes(std::span<const Material> tet_materials,
                                       std::span<const std::uint8_t> fixed_nodes, EngineKind method,
                                       const EngineSettings& engine_settings,
                                       hal::JobSystem* /*jobs*/) {
  const std::vector<SubVolumeBox> boxes = split_grid(
      grid_.nodes, Eigen::Vector3i(settings_.sub_volumes.data()), settings_.overlap_nodes);
  subs_.resize(boxes.size());
  // How many sub-volumes mesh each grid tet.
  std::vector<int> tet_copies(static_cast<std::size_t>(mesh_.tet_count()), 0);
  std::vector<std::vector<int>> sub_tets(boxes.size());
  for (std::size_t s = 0; s < boxes.size(); ++s) {
    extract_sub_mesh(grid_, mesh_, boxes[s], &sub_tets[s]);
    for (int t : sub_tets[s]) ++tet_copies[t];
  }
  // The region's surface, where the probe can touch it: a sub-volume's own boundary also runs
  // along its seams, inside the tissue.
  const std::vector<std::uint8_t> region_surface = geometry::boundary_node_flags(mesh_);
  for (std::size_t s = 0; s < boxes.size(); ++s) {
    SubVolume& sub = subs_[s];
    sub.box = boxes[s];
    const geometry::TetMesh mesh = extract_sub_mesh(grid_, mesh_, sub.box);
    std::vector<Material> materials;
    materials.reserve(sub_tets[s].size());
    for (int t : sub_tets[s]) {
      materials.push_back(tet_materials[t]);
      if (settings_.split_overlap_stiffness) materials.back().youngs_modulus_kpa /= tet_copies[t];
    }
    std::vector<std::uint8_t> fixed(static_cast<std::size_t>(mesh.node_count()));
    std::vector<std::uint8_t> surface(fixed.size());
    sub.global_node.resize(fixed.size());
    for (int k = 0, l = 0; k < sub.box.nodes.z(); ++k) {
      for (int j = 0; j < sub.box.nodes.y(); ++j) {
        for (int i = 0; i < sub.box.nodes.x(); ++i, ++l) {
          const Eigen::Vector3i g = sub.box.first_node + Eigen::Vector3i(i, j, k);
          sub.global_node[l] = grid_.node_index(g.x(), g.y(), g.z());
          fixed[l] = fixed_nodes[sub.global_node[l]];
          surface[l] = region_surface[sub.global_node[l]];
        }
      }
    }
    // A frame is refused when more than a fraction of the tets invert; a probe's rim folds about
    // as many tets in a sub-volume as in one piece, so the same fraction of a sub-volume's far
    // fewer tets would refuse what one piece accepts, and the seam would tear open between a
    // sub-volume that refused and one that did not. Each keeps the one-piece count instead.
    const double tet_share = static_cast<double>(mesh_.tet_count()) / mesh.tet_count();
    EngineSettings settings = engine_settings;
    // A frame in exchanges_per_frame parts: the same steps and iterations in all.
    const int parts = exchanges_per_frame_;
    settings.msds.steps_per_frame /= parts;
    settings.msds.implicit_steps_per_frame =
        std::max(1, settings.msds.implicit_steps_per_frame / parts);
    settings.fem.pcg_iterations_per_frame =
        std::max(1, settings.fem.pcg_iterations_per_frame / parts);
    settings.corotational.pcg_iterations_per_frame =
        std::max(1, settings.corotational.pcg_iterations_per_frame / parts);
    const bool stick = settings.corotational.contact.model == HeldContactModel::kStick;
    settings.corotational.turn_check_interval_frames =
        stick ? 1 : settings_.corotational_turn_check_interval_frames;
    // Face neighbours update in turn (on the volume's exchange clock, set before each step,
    // whichever of them step), so a frame with many sub-volumes in the probe's reach pays for
    // about 1 / interval of their rotations.
    settings.corotational.rotation_update_interval_frames =
        stick ? 1 : settings_.corotational_rotation_update_interval_frames;
    settings.corotational.rotation_update_phase =
        sub.box.index.sum() % settings.corotational.rotation_update_interval_frames;
    settings.corotational.max_update_turns_held =
        stick ? 0 : settings_.corotational_update_turns_held;
    for (double* fraction :
         {&settings.fem.max_inverted_fraction, &settings.msds.max_inverted_fraction,
          &settings.exact.max_inverted_fraction, &settings.corotational.max_inverted_fraction}) {
      *fraction = std::min(1.0, *fraction * tet_share);
    }
    // One sub-volume per job-system task: each engine runs single-threaded.
    try {
      sub.engine = make_engine(method, mesh, materials, fixed, settings, surface);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("StitchedVolume: " + sub_name(sub.box) + ": " + e.what());
    }
    sub.corotational = dynamic_cast<CorotationalFem*>(sub.engine.get());
    if (!sub.engine->supports_anchor_springs()) {
      throw std::invalid_argument("StitchedVolume: " + std::string(sub.engine->name()) +
                                  " cannot be stitched (it takes no anchor springs); use pcg, "
                                  "corotational, msds-explicit or msds-implicit");
    }
    sub.previous_positions_mm = mesh.rest_positions_mm;
    sub.revert_mm = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(mesh.node_count()));
    sub.cut_back_mm = sub.revert_mm;
    sub.positions_mm = sub.engine->deformed_positions_mm();
    const Eigen::Vector3i blocks =
        (sub.box.nodes.array() + kReachBlockNodes - 1) / kReachBlockNodes;
    sub.node_block.resize(sub.global_node.size());
    for (int k = 0, l = 0; k < sub.box.nodes.z(); ++k) {
      for (int j = 0; j < sub.box.nodes.y(); ++j) {
        for (int i = 0; i < sub.box.nodes.x(); ++i, ++l) {
          sub.node_block[l] =
              i / kReachBlockNodes +
              blocks.x() * (j / kReachBlockNodes + blocks.y() * (k / kReachBlockNodes));
        }
      }
    }
    const auto block_count = static_cast<std::size_t>(blocks.prod());
    sub.block_node_start.assign(block_count + 1, 0);
    for (const int b : sub.node_block) ++sub.block_node_start[b + 1];
    std::partial_sum(sub.block_node_start.begin(), sub.block_node_start.end(),
                     sub.block_node_start.begin());
    sub.block_nodes.resize(sub.node_block.size());
    std::vector<int> filled(sub.block_node_start.begin(), sub.block_node_start.end() - 1);
    for (int l = 0; l < static_cast<int>(sub.node_block.size()); ++l) {
      sub.block_nodes[filled[sub.node_block[l]]++] = l;
    }
    sub.block_bounds.resize(block_count);
    sub.block_center_mm.resize(block_count);
    sub.block_half_diagonal_mm.resize(block_count);
    sub.block_near_probe.resize(block_count);
  }
}

void StitchedVolume::build_copies(std::span<const Material> tet_materials) {
  const int n = mesh_.node_count();
  // Only the shared nodes' copies are listed: side by side, the seams' bookkeeping reads them
  // (and the loads and pulls kept per copy) in fewer cache lines than among the many nodes of
  // one sub-volume alone.
  std::vector<int> copy_count(static_cast<std::size_t>(n), 0);
  for (const auto& sub : subs_) {
    for (int g : sub.global_node) ++copy_count[g];
  }
  copies_begin_.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int g = 0; g < n; ++g) {
    copies_begin_[g + 1] = copies_begin_[g] + (copy_count[g] > 1 ? copy_count[g] : 0);
  }
  copies_.resize(copies_begin_[n]);
  std::vector<int> fill(copies_begin_.begin(), copies_begin_.end() - 1);
  for (int s = 0; s < sub_volume_count(); ++s) {
    const auto& global = subs_[s].global_node;
    for (int l = 0; l < static_cast<int>(global.size()); ++l) {
      if (copy_count[global[l]] > 1) copies_[fill[global[l]]++] = {s, l};
    }
  }
  // The seam's stiffness follows the stiffest tissue at the node, so a stiff inclusion's seam
  // gapes no more than soft tissue's.
  std::vector<double> stiffest_kpa(static_cast<std::size_t>(n), 0.0);
  for (int t = 0; t < mesh_.tet_count(); ++t) {
    for (int node : mesh_.tets[t]) {
      stiffest_kpa[node] = std::max(stiffest_kpa[node], tet_materials[t].youngs_modulus_kpa);
    }
  }
  seam_stiffness_mn_per_mm_.assign(static_cast<std::size_t>(n), 0.0);
  for (int g = 0; g < n; ++g) {
    if (copies_begin_[g + 1] - copies_begin_[g] < 2) continue;
    shared_nodes_.push_back(g);
    seam_stiffness_mn_per_mm_[g] = settings_.spring_stiffness_per_modulus_mm * stiffest_kpa[g];
  }
  const auto count = static_cast<std::size_t>(sub_volume_count());
  shared_node_count_.assign(count * count, 0);
  for (const int g : shared_nodes_) {
    for (int a = copies_begin_[g]; a < copies_begin_[g + 1]; ++a) {
      for (int b = copies_begin_[g]; b < copies_begin_[g + 1]; ++b) {
        if (a != b) ++shared_node_count_[copies_[a].sub * count + copies_[b].sub];
      }
    }
  }
  for (int s = 0; s < sub_volume_count(); ++s) {
    SubVolume& sub = subs_[s];
    for (int l = 0; l < static_cast<int>(sub.global_node.size()); ++l) {
      const int g = sub.global_node[l];
      if (seam_stiffness_mn_per_mm_[g] <= 0.0 || fixed_[g]) continue;
      sub.shared_local.push_back(l);
      int c = copies_begin_[g];
      while (copies_[c].sub != s) ++c;
      sub.shared_copy.push_back(c);
    }
    sub.anchors.resize(sub.shared_local.size());
  }
}

void StitchedVolume::take_positions(SubVolume& sub) {
  sub.positions_mm = sub.engine->deformed_positions_mm();
  for (std::size_t k = 0; k < sub.shared_local.size(); ++k) {
    copy_positions_mm_[sub.shared_copy[k]] = sub.positions_mm[sub.shared_local[k]];
  }
}

Eigen::Vector3d StitchedVolume::copies_sum(int g) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) sum += copy_positions_mm_[c];
  return sum;
}

EngineStepStats StitchedVolume::step(const ProbeCollider* probe, double frame_dt_s) {
  return step_within(probe, frame_dt_s, {});
}

EngineStepStats StitchedVolume::step_within(const ProbeCollider* probe, double frame_dt_s,
                                            const StepBudget& may_continue) {
  return step_sharing(probe, frame_dt_s, may_continue, {});
}

EngineStepStats StitchedVolume::step_sharing(const ProbeCollider* probe, double frame_dt_s,
                                             const StepBudget& may_continue,
                                             const TimeLeftUs& time_left_us) {
  for (auto& sub : subs_) sub.stepped = sub.moved = false;
  // The coarse step first, from the shape the last frame left: the sub-volumes' own steps then
  // smooth what it leaves near the probe and at the seams, and the contacts are decided on their
  // answer, not on the coarse field's.
  correct_coarsely();
  // The sub-volumes that step whatever the time: those in the probe's reach (touched), and those
  // the last frame's torn seam left standing.
  const int touched = plan_frame(probe);
  const int in_reach = static_cast<int>(
      std::ranges::count_if(subs_, [](const SubVolume& sub) { return sub.touched; }));
  const int batch = jobs_ != nullptr ? std::max(1, jobs_->thread_count()) : 1;
  // The sub-volumes the probe may touch always step: skipping one would let the probe pass
  // through the tissue. So do those a torn seam left standing last frame.
  // The first exchange picks which sub-volumes step this frame; the others step the same ones.
  const int parts = exchanges_per_frame_;
  const double part_dt_s = frame_dt_s / parts;
  ++exchange_count_;  // the first exchange's
  for (int s = 0; s < sub_volume_count(); ++s) {
    const CorotationalFem* fem = subs_[s].corotational;
    update_forced_[s] = fem != nullptr && fem->update_forced_at(exchange_count_);
  }
  // The sub-volumes take the frame's budget as one piece does: the CG methods iterate while the
  // frame has time (warm-started, they catch up over the next frames), the explicit MSDS steps
  // while there is time and retries a rejected frame with smaller steps only while there is. The
  // large case's touched sub-volumes took 22 ms (PCG FEM, 20 iterations each) and 34 ms (implicit
  // MSDS) of the simulation's 4 ms at p50 with full solves. The sub-volumes step on the job
  // system's threads, and the budget is one clock for them all.
  StepBudget sub_budget;
  if (may_continue) {
    sub_budget = [this, &may_continue] {
      std::lock_guard lock(budget_mutex_);
      return may_continue();
    };
  }
  // With the time left known, the frame's time is shared out evenly over the batches due that fit
  // at their least cost (one CG iteration, the explicit MSDS's fixed steps: last frame's), the
  // touched ones first; a batch stops its own work once its share is spent, and the time the work
  // after the steps took last frame is kept back. Without sharing, the touched sub-volumes' CG
  // took the whole frame and their neighbours never stepped: the seams between them opened (the
  // large case's sweep-press: 0.4-2.5 mm; 0.13-0.17 shared). One pointer captured: no allocation.
  // A batch's work does not end at its first "no": an implicit MSDS's CG stops, then its next
  // step computes every spring's force and block and one iteration more (the large case: about
  // as long as its CG had). What the batches did after their first "no" last frame is kept back
  // too, so that the batch ends within its share instead of starting its tail there.
  struct BatchShare {
    StitchedVolume* self;
    const StepBudget* frame;
    const TimeLeftUs* time_left_us;
    std::int64_t reserve_us;
    std::int64_t left_at_first_question_us;  // -1 until the batch's first question
    std::int64_t left_at_first_no_us;        // -1 until the batch's first "no"
  } share{this, &may_continue, &time_left_us, 0, -1, -1};
  const StepBudget share_budget = [&share] {
    std::lock_guard lock(share.self->budget_mutex_);
    const std::int64_t left_us = (*share.time_left_us)();
    if (share.left_at_first_question_us < 0) share.left_at_first_question_us = left_us;
    const bool yes = (*share.frame)() && left_us > share.reserve_us + share.self->batch_tail_us_;
    if (!yes && share.left_at_first_no_us < 0) share.left_at_first_no_us = left_us;
    return yes;
  };
  const int scheduled = static_cast<int>(schedule_.size());
  const int touched_batches = (touched + batch - 1) / batch;
  const int other_batches = (scheduled - touched + batch - 1) / batch;
  const bool shares = may_continue && time_left_us;
  // The time left is shared over the frame's exchanges evenly: this first one plans its batches
  // on its part and keeps the others' back.
  const std::int64_t left_at_start_us =
      shares ? std::max<std::int64_t>(time_left_us() - after_steps_us_, 0) / parts : 0;
  const std::int64_t later_parts_us = left_at_start_us * (parts - 1);
  const int batches_that_fit =
      shares && batch_cost_us_ > 0 ? static_cast<int>(left_at_start_us / batch_cost_us_) : 1;
  // At least one: a frame with nothing touched still shares its time among those that run.
  const int due_batches = std::max(
      1, touched_batches + std::clamp(batches_that_fit - touched_batches, 0, other_batches));
  // The due sub-volumes (all without a budget) in batches that share the fewest seam nodes.
  const int must_step = order_into_batches(
      touched, shares ? std::min(scheduled, due_batches * batch) : scheduled, batch);
  std::int64_t batch_cost_us = 0;
  std::int64_t update_batch_cost_us = -1;  // -1: no batch brought a warped system up to date
  bool cost_measured = false;              // by a batch that held no update
  int updates_held = 0;                    // over the frame's batches and exchanges
  std::int64_t batch_tail_us = -1;
  // Steps schedule_[first, first + count) with `reserve_us` kept back from its share, and
  // measures the batch's least cost and its tail in every exchange: with one implicit MSDS step
  // a part, a later exchange's batch may be the only one told no.
  const auto run_batch = [&](int first, int count, std::int64_t reserve_us, bool first_part) {
    share.reserve_us = reserve_us;
    share.left_at_first_question_us = share.left_at_first_no_us = -1;
    const std::int64_t left_before_us = shares ? time_left_us() : 0;
    // A batch whose share (left less what is kept back) is no more than what a batch with an
    // update took (a full frame, or a late one; at least a batch's least cost) has its
    // corotational sub-volumes hold their due updates: the time the rotations would take goes to
    // the CG, whose one iteration a frame is what kept the seam presses' forces at 1.6 times the
    // solved run's (1.2 held; [stitching] corotational_update_turns_held). Held only where the
    // share did not cover the least cost, a first batch of six touched took its updates in a
    // share of a third of the frame and ran past it by 0.5-0.7 ms.
    const bool hold_updates =
        shares && left_before_us - reserve_us <= std::max(batch_cost_us_, update_batch_cost_us_);
    const std::span<const int> subs = std::span(schedule_).subspan(first, count);
    step_batch(subs, probe, part_dt_s, first_part, shares ? share_budget : sub_budget,
               hold_updates);
    const auto held = static_cast<int>(std::ranges::count_if(subs, [this](int s) {
      return subs_[s].corotational != nullptr && subs_[s].corotational->update_held();
    }));
    updates_held += held;
    if (!shares) return;
    const std::int64_t left_at_end_us = time_left_us();
    // Up to the first question, or the whole batch if none asked (no further work wanted). Not
    // from a batch that held an update: its cost without it would plan more batches next frame,
    // whose shares would not cover the updates taken whatever the time.
    const std::int64_t left_after_us =
        share.left_at_first_question_us >= 0 ? share.left_at_first_question_us : left_at_end_us;
    const bool updated = std::ranges::any_of(subs, [this](int s) {
      return subs_[s].corotational != nullptr && subs_[s].corotational->warped_system_updated();
    });
    if (updated) {
      update_batch_cost_us = std::max(update_batch_cost_us, left_before_us - left_after_us);
    }
    if (held == 0) batch_cost_us = std::max(batch_cost_us, left_before_us - left_after_us);
    cost_measured = cost_measured || held == 0;
    if (share.left_at_first_no_us >= 0) {
      batch_tail_us = std::max(batch_tail_us, share.left_at_first_no_us - left_at_end_us);
    }
  };
  int next = 0;
  int b = 0;
  const auto step_next_batch = [&](int end) {
    const int count = std::min(batch, end - next);
    const int batches_after = std::max(due_batches - 1 - b, 0);
    run_batch(next, count,
              after_steps_us_ + later_parts_us + left_at_start_us * batches_after / due_batches,
              true);
    next += count;
    ++b;
  };
  while (next < must_step) step_next_batch(must_step);
  // A planned batch while time is left (its share was sized to fit it); a further one only if one
  // at its least cost still ends in time.
  const auto another_batch_fits = [&] {
    if (!may_continue) return true;
    if (!shares) return may_continue();
    const std::lock_guard lock(budget_mutex_);
    return time_left_us() >
           (b < due_batches ? 0 : batch_cost_us_) + after_steps_us_ + later_parts_us;
  };
  // A corotational sub-volume whose due update can be held no more (update_forced_at) costs a
  // batch with an update, not a batch at its least: once such a batch no longer fits, the rest
  // of the frame steps the others and it waits for a frame with the time (under the large
  // case's seam presses an extra sub-volume's forced update made 43 of the 89 frames whose
  // simulation took over 5 ms), kMostTimesAnUpdateWaits times at most between two updates (a
  // press that never leaves the time would otherwise keep its rotations as they were for good).
  int end = scheduled;
  const auto defer_forced_updates = [&] {
    if (!shares || update_batch_cost_us_ <= 0 ||
        time_left_us() > update_batch_cost_us_ + after_steps_us_ + later_parts_us) {
      return;
    }
    batched_.clear();  // free after order_into_batches: the deferred, in order
    int kept = next;
    for (int i = next; i < end; ++i) {
      SubVolume& sub = subs_[schedule_[i]];
      if (update_forced_[schedule_[i]] && sub.times_update_waited < kMostTimesAnUpdateWaits) {
        ++sub.times_update_waited;  // once a frame: past `end` it is not looked at again
        batched_.push_back(schedule_[i]);
      } else {
        schedule_[kept++] = schedule_[i];
      }
    }
    std::copy(batched_.begin(), batched_.end(), schedule_.begin() + kept);
    end = kept;
  };
  while (next < end && another_batch_fits()) {
    defer_forced_updates();
    if (next < end) step_next_batch(end);
  }
  // The later exchanges step the same sub-volumes, each batch its even share of the part's time
  // (the part's: what is left over the parts to go).
  const int batches_stepped = (next + batch - 1) / batch;
  for (int part = 1; part < parts; ++part) {
    ++exchange_count_;
    const std::int64_t part_us =
        shares ? std::max<std::int64_t>(time_left_us() - after_steps_us_, 0) / (parts - part) : 0;
    for (int j = 0; j < batches_stepped; ++j) {
      run_batch(j * batch, std::min(batch, next - j * batch),
                after_steps_us_ + part_us * (parts - part - 1) +
                    part_us * (batches_stepped - 1 - j) / batches_stepped,
                false);
    }
  }
  if (shares && cost_measured) batch_cost_us_ = batch_cost_us;
  if (shares && update_batch_cost_us >= 0) update_batch_cost_us_ = update_batch_cost_us;
  // Kept from the last frame where a batch was told no (one with time to spare says nothing).
  if (shares && batch_tail_us >= 0) batch_tail_us_ = batch_tail_us;
  const std::int64_t left_after_steps_us = shares ? time_left_us() : 0;
  const std::span<const int> stepped = std::span(schedule_).first(next);
  DivergenceCause refusal = DivergenceCause::kNone;
  bool refused = refuses_frame(stepped, refusal);
  // With nothing in the probe's reach the tissue springs back toward rest, and a seam it tears
  // on the way would be the same frame again, refused for ever (a released press, the springs
  // alone: 200 of 200 frames, the tissue left 3.8 mm deep under no probe). Accepting the tear
  // instead let seams open to 7-12 mm in the large soak. The frame is cut back along its update,
  // to the largest part of it that tears nothing: the tissue comes back over a few frames.
  const bool cut_back =
      refused && refusal == DivergenceCause::kSeamTorn && in_reach == 0 && cut_back_frame(stepped);
  refused = refused && !cut_back;
  // A sub-volume marked to step has, once its frame is kept; the marks of a frame cut back came
  // from tears its kept part does not have.
  for (int s = 0; s < sub_volume_count(); ++s) {
    if (cut_back || (!refused && subs_[s].stepped)) step_next_[s] = 0;
  }
  // A refused frame with the probe in reach is tried again at another pose (the session's
  // RefusedPress); one with nothing in reach is the same frame again unless the loads change.
  // A frame cut back is the tissue springing back with nothing in reach: the loads are
  // released as for a refusal, else they keep a seam they opened at the bound.
  const SeamLoads loads = settings_.seam_load_rate <= 0.0 ? SeamLoads::kKeep
                          : cut_back                      ? SeamLoads::kHalve
                          : !refused                      ? SeamLoads::kRemember
                          : in_reach == 0                 ? SeamLoads::kHalve
                                                          : SeamLoads::kKeep;
  if (refused) {
    revert_frame(stepped);
  } else {
    join_held_copies();
    correct_finely(may_continue);
  }
  update_coarse_residuals(stepped);
  EngineStepStats out;
  for (const auto& sub : subs_) {
    if (!sub.stepped) continue;
    const EngineStepStats& s = sub.last_stats;
    out.iterations += s.iterations;
    out.relative_residual = std::max(out.relative_residual, s.relative_residual);
    out.contact_nodes += s.contact_nodes;
    out.contact_force_n += s.contact_force_n;
    out.inverted_tets = std::max(out.inverted_tets, s.inverted_tets);
    out.diverged = out.diverged || s.diverged;
    out.cut_short = out.cut_short || s.cut_short;
    // The cause behind the worst recovery (the first sub-volume's, of equals).
    if (s.diverged && (out.cause == DivergenceCause::kNone ||
                       worse_recovery(s.recovery, out.recovery) != out.recovery)) {
      out.cause = s.cause;
    }
    out.recovery = worse_recovery(out.recovery, s.recovery);
  }
  // Deferred sub-volumes, or a stepped one's solve stopped by the budget.
  out.cut_short = out.cut_short || next < scheduled;
  if (cut_back) {
    out.diverged = true;
    out.cause = DivergenceCause::kSeamTorn;
    out.recovery = worse_recovery(out.recovery, Recovery::kSubstepped);
  }
  if (refused) {
    // One piece's verdict on the press (the session then holds the probe where the tissue last
    // took it), not a frame left unfinished, unless a sub-volume kept its last good shape only
    // because the budget ran out before smaller steps were tried: as for one piece, no verdict,
    // and the next frame tries again.
    out.diverged = true;
    out.cause = refusal;
    out.recovery = Recovery::kKeptLastGood;
    out.cut_short = std::ranges::any_of(stepped, [this](int s) {
      const EngineStepStats& stats = subs_[s].last_stats;
      return stats.recovery == Recovery::kKeptLastGood && stats.cut_short;
    });
  }
  finish_frame(loads);
  if (shares) after_steps_us_ = std::max<std::int64_t>(left_after_steps_us - time_left_us(), 0);
  stats_.sub_volumes_touched = in_reach;
  stats_.sub_volumes_stepped = next;
  stats_.sub_volumes_deferred = 0;
  for (const auto& sub : subs_) stats_.sub_volumes_deferred += !sub.stepped && !sub.asleep;
  stats_.updates_held = updates_held;
  return out;
}

int StitchedVolume::plan_frame(const ProbeCollider* probe) {
  const int count = sub_volume_count();
  std::fill(due_.begin(), due_.end(), 0);
  schedule_.clear();
  for (int s = 0; s < count; ++s) {
    SubVolume& sub = subs_[s];
    sub.touched = probe != nullptr && within_reach(sub, *probe);
    // A sub-volume the last frame's torn seam was left standing on steps with the touched ones.
    if (sub.touched || step_next_[s]) {
      sub.asleep = false;
      due_[s] = 1;
      schedule_.push_back(s);
    }
  }
  const int touched = static_cast<int>(schedule_.size());
  if (!settings_.selective) {
    for (int s = 0; s < count; ++s) {
      if (!due_[s]) schedule_.push_back(s);
      subs_[s].asleep = false;
    }
  } else {
    // Neighbours of touched sub-volumes (faces, edges and corners).
    for (int t = 0; t < touched; ++t) {
      if (!subs_[schedule_[t]].touched) continue;  // one a torn seam left standing
      const Eigen::Vector3i centre = subs_[schedule_[t]].box.index;
      for (int s = 0; s < count; ++s) {
        if (due_[s]) continue;
        if ((subs_[s].box.index - centre).cwiseAbs().maxCoeff() <= 1) {
          due_[s] = 1;
          subs_[s].asleep = false;
          schedule_.push_back(s);
        }
      }
    }
    // Then the awake ones pulled hardest by their seams (the published paper picked one at
    // random and named this as the better choice), the pull weighted by the frames each has
    // waited: a seam pulls both its sides alike, and the side that steps cannot close it alone.
    for (int extra = 0; extra < settings_.extra_sub_volumes_per_frame; ++extra) {
      int best = -1;
      for (int s = 0; s < count; ++s) {
        if (due_[s] || subs_[s].asleep) continue;
        if (best < 0 || priority(s) > priority(best)) best = s;
      }
      if (best < 0) break;
      due_[best] = 1;
      schedule_.push_back(best);
    }
  }
  // Ties in sub-volume order; std::sort, because std::stable_sort takes a buffer from the heap.
  std::sort(schedule_.begin() + touched, schedule_.end(), [&](int a, int b) {
    const double pa = priority(a), pb = priority(b);
    return pa > pb || (pa == pb && a < b);
  });
  return touched;
}

int StitchedVolume::order_into_batches(int touched, int due, int batch) {
  // Two sub-volumes of a batch step at once, each anchored to where the other's copies were:
  // where they share a seam, each copy takes its twin's old place and the twin its own (the
  // Jacobi swap), and under a moving probe that gap grows from frame to frame (the large case's
  // sweep-press, every due sub-volume stepped: 0.46-1.23 mm on two threads, 0.14 mm on one). A
  // batch is therefore filled, in the schedule's order, with the sub-volumes that share the
  // fewest nodes with it, none where the schedule holds such: a sub-volume then mostly steps
  // from its neighbours' new copies, as on one thread (0.097 mm). Only among the due: filling a
  // batch from further down the schedule would step a sub-volume that pulls less on its seams
  // instead of one that pulls more.
  const int count = sub_volume_count();
  batched_.clear();
  std::fill(placed_.begin(), placed_.end(), 0);
  int must_step = 0;
  for (int i = 0; i < due; ++i) {
    if (placed_[i]) continue;
    const std::size_t first = batched_.size();
    batched_.push_back(schedule_[i]);
    placed_[i] = 1;
    if (i < touched) must_step = static_cast<int>(batched_.size());
    while (static_cast<int>(batched_.size() - first) < batch) {
      // A touched sub-volume's batch is filled with touched ones while any is left: with
      // untouched partners the touched ones would take twice the batches, which step whatever
      // the time (the implicit MSDS's large soak: simulation p90 4.9 → 6.2 ms).
      const bool touched_left =
          i < touched && std::any_of(placed_.begin() + i + 1, placed_.begin() + touched,
                                     [](std::uint8_t placed) { return placed == 0; });
      const int end = touched_left ? touched : due;
      int best = -1;
      long best_shared = 0;
      for (int j = i + 1; j < end && !(best >= 0 && best_shared == 0); ++j) {
        if (placed_[j]) continue;
        long shared = 0;
        for (std::size_t k = first; k < batched_.size(); ++k) {
          shared +=
              shared_node_count_[static_cast<std::size_t>(batched_[k]) * count + schedule_[j]];
        }
        if (best < 0 || shared < best_shared) best = j, best_shared = shared;
      }
      if (best < 0) break;
      batched_.push_back(schedule_[best]);
      placed_[best] = 1;
      if (best < touched) must_step = static_cast<int>(batched_.size());
    }
  }
  std::copy(batched_.begin(), batched_.end(), schedule_.begin());
  // Every batch that holds a touched sub-volume steps.
  return std::min(due, (must_step + batch - 1) / batch * batch);
}

bool StitchedVolume::within_reach(const SubVolume& sub, const ProbeCollider& probe) const {
  const double reach_mm = kReachMarginMm + stats_.coarse_move_mm;
  for (std::size_t b = 0; b < sub.block_center_mm.size(); ++b) {
    // The probe's signed distance changes no faster than the point moves: no node of a block is
    // within reach when the block's centre is farther than its half diagonal.
    if (probe.signed_distance_mm(sub.block_center_mm[b]) >
        sub.block_half_diagonal_mm[b] + reach_mm) {
      continue;
    }
    // A block that may reach is looked at node by node: a block is several millimetres across,
    // and on its own it counted sub-volumes whose nearest node was that far from the probe (the
    // large case's seam presses: one sub-volume in nine of those it counted).
    for (int i = sub.block_node_start[b]; i < sub.block_node_start[b + 1]; ++i) {
      if (probe.signed_distance_mm(sub.positions_mm[sub.block_nodes[i]]) <= reach_mm) return true;
    }
  }
  return false;
}

double StitchedVolume::priority(int sub) const {
  return subs_[sub].max_seam_force_mn * (1.0 + subs_[sub].frames_waiting);
}

void StitchedVolume::refresh_anchors(int s, const ProbeCollider* probe) {
  SubVolume& sub = subs_[s];
  // Which blocks' twins may lie inside the probe: a twin is within the seam's last widest gap of
  // its copy, and the signed distance changes no faster than the point moves.
  const bool predict = probe != nullptr && sub.touched;
  if (predict) {
    for (std::size_t b = 0; b < sub.block_center_mm.size(); ++b) {
      sub.block_near_probe[b] =
          probe->signed_distance_mm(sub.block_center_mm[b]) <=
          sub.block_half_diagonal_mm[b] + sub.max_seam_gap_mm + kReachMarginMm;
    }
  }
  for (std::size_t i = 0; i < sub.shared_local.size(); ++i) {
    const int local = sub.shared_local[i];
    const int g = sub.global_node[local];
    const int own = sub.shared_copy[i];
    Eigen::Vector3d others = Eigen::Vector3d::Zero();
    for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
      if (c != own) others += copy_positions_mm_[c];
    }
    const int count = copies_begin_[g + 1] - copies_begin_[g] - 1;
    // count springs of stiffness k to the other copies pull as one of k × count to their mean.
    // Where the probe will put a twin it has pushed into: anchored to where the twin was before
    // the step, a copy the probe catches alongside its twin is pulled back off the probe by the
    // seam spring (the large case's touch-down frames read 23 N with the PCG FEM against one
    // piece's 2.4 N, and 3 N five frames later).
    Eigen::Vector3d target = others / count;
    if (predict && sub.block_near_probe[sub.node_block[local]] &&
        probe->signed_distance_mm(target) < 0.0) {
      target = probe->closest_surface_point(target).point_mm;
    }
    // The load the seam carried, as the spring's pull from that much further on.
    const double stiffness = seam_stiffness_mn_per_mm_[g] * count;
    target += seam_load_mn_[own] / stiffness;
    sub.anchors[i] = {local, target, stiffness};
  }
  sub.engine->set_anchor_springs(sub.anchors);
}

void StitchedVolume::step_batch(std::span<const int> subs, const ProbeCollider* probe,
                                double frame_dt_s, bool first_part, const StepBudget& budget,
                                bool hold_updates) {
  // Anchors first, from positions no sub-volume of the batch has moved yet: the batch's steps
  // are then independent and run in parallel.
  hal::parallel_for(jobs_, static_cast<int>(subs.size()),
                    [&](int i) { refresh_anchors(subs[i], probe); });
  auto step_one = [&](int i) {
    SubVolume& sub = subs_[subs[i]];
    if (first_part) {
      const auto before = sub.engine->deformed_positions_mm();
      std::copy(before.begin(), before.end(), sub.previous_positions_mm.begin());
    }
    if (sub.corotational != nullptr) {
      sub.corotational->set_update_clock(exchange_count_);
      if (hold_updates) sub.corotational->hold_next_update();
    }
    const EngineStepStats s = sub.engine->step_within(probe, frame_dt_s, budget);
    if (first_part) {
      sub.last_stats = s;
    } else {
      // The frame's stats: work summed, the latest contact, the worst of the rest.
      EngineStepStats& f = sub.last_stats;
      f.iterations += s.iterations;
      f.relative_residual = s.relative_residual;
      f.contact_nodes = s.contact_nodes;
      f.contact_force_n = s.contact_force_n;
      f.inverted_tets = std::max(f.inverted_tets, s.inverted_tets);
      if (!f.diverged) f.cause = s.cause;  // the frame's first
      f.diverged = f.diverged || s.diverged;
      f.recovery = worse_recovery(f.recovery, s.recovery);
    }
    take_positions(sub);
    sub.stepped = sub.moved = true;
  };
  hal::parallel_for(jobs_, static_cast<int>(subs.size()), step_one);
}

void StitchedVolume::update_coarse_residuals(std::span<const int> stepped) {
  if (!coarse_) return;
  const auto update = [&](int i) { coarse_->update(stepped[i], *subs_[stepped[i]].engine); };
  hal::parallel_for(jobs_, static_cast<int>(stepped.size()), update);
}

void StitchedVolume::correct_finely(const StepBudget& may_continue) {
  stats_.fine_iterations = 0;
  stats_.fine_move_mm = 0.0;
  if (!fine_) return;
  for (std::size_t s = 0; s < subs_.size(); ++s) stepped_flags_[s] = subs_[s].stepped ? 1 : 0;
  constexpr double kRelativeTolerance = 1e-3;  // of the load
  const FineCorrection::Result result =
      fine_->correct(engines_, stepped_flags_, settings_.fine_correction_iterations,
                     kRelativeTolerance, may_continue, jobs_);
  stats_.fine_iterations = result.iterations;
  stats_.fine_move_mm = result.largest_move_mm;
  for (auto& sub : subs_) {
    if (sub.stepped) take_positions(sub);
  }
}

bool StitchedVolume::refuses_frame(std::span<const int> stepped, DivergenceCause& cause) {
  for (int s : stepped) {
    const EngineStepStats& stats = subs_[s].last_stats;
    if (stats.recovery == Recovery::kReset || stats.recovery == Recovery::kKeptLastGood) {
      cause = stats.cause;
      return true;
    }
  }
  if (tears_a_seam(stepped, true)) {
    cause = DivergenceCause::kSeamTorn;
    return true;
  }
  return false;
}

bool StitchedVolume::tears_a_seam(std::span<const int> stepped, bool mark_standing) {
  // A seam already past the bound may close or hold, not widen by more than rounding and a
  // still probe's warm-started drift (refusing those would hold the probe at random); one
  // within it may not cross it.
  constexpr double kWideningToleranceMm = 1e-3;
  const auto torn_at = [&](int g) {
    const double limit = seam_gap_mm_[g] > settings_.refuse_gap_mm
                             ? seam_gap_mm_[g] + kWideningToleranceMm
                             : settings_.refuse_gap_mm;
    return widest_copy_gap_mm(g) > limit;
  };
  // The stepped sub-volumes' seams: a refusal reverts only those, and the copies of a node move
  // alike under the corrections (the coarse one but for held copies and barely moved
  // sub-volumes). A gap widens by no more than its copies moved, so a sub-volume whose widest
  // seam (as of the last frame), its own seam copies' largest move in their steps, the largest
  // of any stepped sub-volume's and twice the coarse correction's largest move stay within the
  // bound tears nothing, and its seams are not looked at node by node (the seam presses: 0.13 ms
  // p50 of a frame node by node on one thread, 0.04 ms so; the sum rarely comes near the 3 mm).
  hal::parallel_for(jobs_, static_cast<int>(stepped.size()), [&](int i) {
    const SubVolume& sub = subs_[stepped[i]];
    double most_squared = 0.0;
    for (const int local : sub.shared_local) {
      most_squared = std::max(
          most_squared, (sub.positions_mm[local] - sub.previous_positions_mm[local]).squaredNorm());
    }
    seam_move_mm_[stepped[i]] = std::sqrt(most_squared);
  });
  double most_move_mm = 0.0;
  for (const int s : stepped) most_move_mm = std::max(most_move_mm, seam_move_mm_[s]);
  const double margin_mm = most_move_mm + 2.0 * stats_.coarse_move_mm + kWideningToleranceMm;
  subs_to_look_at_.clear();
  for (const int s : stepped) {
    const double widest_mm = subs_[s].max_seam_gap_mm;
    if (widest_mm > settings_.refuse_gap_mm ||
        widest_mm + seam_move_mm_[s] + margin_mm >= settings_.refuse_gap_mm) {
      subs_to_look_at_.push_back(s);
    }
  }
  hal::parallel_for(jobs_, static_cast<int>(subs_to_look_at_.size()), [&](int i) {
    const SubVolume& sub = subs_[subs_to_look_at_[i]];
    tears_seam_[subs_to_look_at_[i]] = std::ranges::any_of(
        sub.shared_local, [&](int local) { return torn_at(sub.global_node[local]); });
  });
  bool torn = false;
  for (const int s : subs_to_look_at_) {
    if (!tears_seam_[s]) continue;
    torn = true;
    if (!mark_standing) break;
    // The torn nodes' copies in sub-volumes that did not step were left where they were while
    // the others moved away: they step next frame.
    for (const int local : subs_[s].shared_local) {
      const int g = subs_[s].global_node[local];
      if (!torn_at(g)) continue;
      for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
        if (!subs_[copies_[c].sub].stepped) step_next_[copies_[c].sub] = 1;
      }
    }
  }
  return torn;
}

void StitchedVolume::revert_frame(std::span<const int> stepped) {
  const auto revert = [&](int i) {
    SubVolume& sub = subs_[stepped[i]];
    frame_start_displacements(sub);
    sub.engine->set_displacements_mm(sub.revert_mm);
    take_positions(sub);
  };
  hal::parallel_for(jobs_, static_cast<int>(stepped.size()), revert);
}

void StitchedVolume::frame_start_displacements(SubVolume& sub) {
  const auto x = sub.engine->deformed_positions_mm();
  const Eigen::VectorXd& u = sub.engine->displacements_mm();
  for (std::size_t l = 0; l < x.size(); ++l) {
    const auto dof = static_cast<Eigen::Index>(3 * l);
    // rest = x − u
    sub.revert_mm.segment<3>(dof) = sub.previous_positions_mm[l] - (x[l] - u.segment<3>(dof));
  }
}

bool StitchedVolume::cut_back_frame(std::span<const int> stepped) {
  constexpr int kHalvings = 8;  // down to 1/256 of the frame's update
  hal::parallel_for(jobs_, static_cast<int>(stepped.size()), [&](int i) {
    SubVolume& sub = subs_[stepped[i]];
    frame_start_displacements(sub);
    sub.cut_back_mm = sub.engine->displacements_mm();
  });
  for (int halving = 0; halving < kHalvings; ++halving) {
    hal::parallel_for(jobs_, static_cast<int>(stepped.size()), [&](int i) {
      SubVolume& sub = subs_[stepped[i]];
      sub.cut_back_mm = 0.5 * (sub.revert_mm + sub.cut_back_mm);  // half of what is left
      sub.engine->set_displacements_mm(sub.cut_back_mm);
      take_positions(sub);
    });
    if (!tears_a_seam(stepped, false)) return true;
  }
  return false;  // the caller reverts the frame
}

template <typename Keep, typename Visit>
void StitchedVolume::for_each_moved_seam_node(Keep keep, Visit visit) {
  if (++node_stamp_counter_ == 0) {  // wrapped (after years at 60 Hz): no stale stamp may match
    std::fill(node_stamp_.begin(), node_stamp_.end(), 0u);
    node_stamp_counter_ = 1;
  }
  const std::uint32_t stamp = node_stamp_counter_;
  for (const auto& sub : subs_) {
    if (!sub.moved) continue;  // read as the loop goes: visit may move a later one
    for (const int local : sub.shared_local) {
      if (!keep(sub, local)) continue;
      const int g = sub.global_node[local];
      if (node_stamp_[g] == stamp) continue;
      node_stamp_[g] = stamp;
      visit(g);
    }
  }
}

void StitchedVolume::join_held_copies() {
  // Held copies that moved this frame (stepped, or moved by the coarse correction) are joined
  // with their twins, held or not moved alike: only the moved sub-volumes' seam nodes are looked
  // at (going over every seam node's copies took 0.3 ms a frame on the large case); copies that
  // did not move were joined when they last did.
  for_each_moved_seam_node(
      [](const SubVolume& sub, int local) { return sub.engine->holds_node(local); },
      [this](int g) { join_held_copies_of(g); });
}

void StitchedVolume::join_held_copies_of(int g) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::AlignedBox3d spread;
  int held = 0;
  for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
    if (!subs_[copies_[c].sub].engine->holds_node(copies_[c].local)) continue;
    const Eigen::Vector3d& x = copy_positions_mm_[c];
    sum += x;
    spread.extend(x);
    ++held;
  }
  // Copies caught this close together are left alone: under the stick contact which nodes a
  // probe catches depends on where each was, and moving them for nothing visible changed the
  // stitched PCG FEM's rim from 1.7 % to 4.4 % of one piece's peak.
  if (held < 2 || spread.diagonal().norm() <= kJoinHeldCopiesMm) return;
  const Eigen::Vector3d mean = sum / held;
  for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
    SubVolume& sub = subs_[copies_[c].sub];
    sub.engine->move_held_node_mm(copies_[c].local, mean);  // leaves a free copy where it is
    sub.positions_mm = sub.engine->deformed_positions_mm();
    copy_positions_mm_[c] = sub.positions_mm[copies_[c].local];  // the one node it moved
    sub.moved = true;
  }
}

void StitchedVolume::correct_coarsely() {
  stats_.coarse_move_mm = 0.0;
  stats_.sub_volumes_corrected = 0;
  if (!coarse_) return;
  for (int g : shared_nodes_) {
    if (fixed_[g]) continue;
    const int begin = copies_begin_[g], end = copies_begin_[g + 1];
    const Eigen::Vector3d sum = copies_sum(g);
    int still = 0;
    for (int c = begin; c < end; ++c) still += coarse_->left_out(copies_[c].sub, copies_[c].local);
    if (still > 0 && still < end - begin) {
      const int x = g % grid_.nodes.x(), y = (g / grid_.nodes.x()) % grid_.nodes.y(),
                z = g / (grid_.nodes.x() * grid_.nodes.y());
      coarse_->add_uneven_seam({x, y, z},
                               seam_stiffness_mn_per_mm_[g] * still * (end - begin - still));
    }
    for (int c = begin; c < end; ++c) {
      // Σ over the other copies of k (x_d − x_c) = k (sum − count·x_c).
      coarse_->add_seam_force(
          copies_[c].sub, copies_[c].local,
          seam_stiffness_mn_per_mm_[g] * (sum - (end - begin) * copy_positions_mm_[c]) +
              seam_load_mn_[c]);
    }
  }
  if (!coarse_->solve()) return;
  // A move smaller than a sleeping sub-volume's own motion is not worth waking it for.
  corrected_.clear();
  for (int s = 0; s < sub_volume_count(); ++s) {
    const double move = coarse_->largest_move_mm(s);
    stats_.coarse_move_mm = std::max(stats_.coarse_move_mm, move);
    if (move > settings_.sleep_motion_mm) corrected_.push_back(s);
  }
  const auto apply = [&](int i) {
    SubVolume& sub = subs_[corrected_[i]];
    coarse_->apply(corrected_[i], *sub.engine);
    take_positions(sub);
    sub.moved = true;
    sub.asleep = false;
  };
  hal::parallel_for(jobs_, static_cast<int>(corrected_.size()), apply);
  stats_.sub_volumes_corrected = static_cast<int>(corrected_.size());
}

void StitchedVolume::update_seam(int g, SeamLoads loads) {
  const int begin = copies_begin_[g], end = copies_begin_[g + 1];
  const int count = end - begin;
  const auto at_hand =
      std::span(copy_positions_mm_)
          .subspan(static_cast<std::size_t>(begin), static_cast<std::size_t>(count));
  const Eigen::Vector3d sum = copies_sum(g);
  shown_[g] = sum / count;  // the published midpoint: no gap shows
  u_.segment<3>(3 * g) = shown_[g] - mesh_.rest_positions_mm[g];
  if (fixed_[g]) {
    seam_gap_mm_[g] = seam_force_mn_[g] = 0.0;
    return;
  }
  int stepped = 0;
  for (int c = begin; c < end; ++c) stepped += subs_[copies_[c].sub].stepped;
  // The springs' pull is added to the loads where every copy stepped this frame: a copy left
  // where it was did not answer the load it was given (with one copy stepped at a time the loads
  // wound up and swung, ±150 mN at a four-copy corner of the large case). Elsewhere the loads
  // fade, so that a region whose copies no longer step together (after the probe has left,
  // one extra sub-volume a frame) is not held deformed by what they last carried. A copy the
  // probe holds does not answer its anchor either (two held apart would wind up for ever): the
  // free copies' change is taken by the held ones between them, and the loads still add up to
  // zero over the node's copies. A refused frame with nothing in the probe's reach halves the
  // loads of the seams it went back on: the loads themselves may tear a seam (a press they
  // carried, released at once, opens the seam by load / k), and kept as they were the same frame
  // would be refused for ever (a 2 × 1 split lifted from: 200 frames refused, the tissue left
  // pressed 3.8 mm under no probe). Halved under a press too, they gave way to the springs alone
  // frame after frame, and the large soak's refused frames rose (1,954 against 896-1,201).
  const bool remember = loads == SeamLoads::kRemember && stepped == count;
  const double fade = loads == SeamLoads::kHalve                         ? 0.5
                      : loads == SeamLoads::kRemember && stepped < count ? kSeamLoadFadePerFrame
                                                                         : 0.0;
  Eigen::Vector3d added = Eigen::Vector3d::Zero();
  int held = 0;
  for (int c = begin; c < end; ++c) {
    // Σ over the other copies of k (x_d − x_c) = k (sum − count·x_c).
    const Eigen::Vector3d pull = seam_stiffness_mn_per_mm_[g] * (sum - count * at_hand[c - begin]);
    seam_load_mn_[c] *= 1.0 - fade;
    if (remember && subs_[copies_[c].sub].engine->holds_node(copies_[c].local)) {
      ++held;
    } else if (remember) {
      // The mean of this frame's pull and the last: a seam whose copies swap sides from frame
      // to frame (each anchored to where the other was) pulls one way and back, and adding each
      // frame's pull fed that swing until the seam tore (the implicit MSDS on a 2 × 1 split:
      // 2.4-3.0 mm within 15-150 frames at rates of 0.1-0.25).
      const Eigen::Vector3d step =
          settings_.seam_load_rate * 0.5 * (pull + seam_pull_before_mn_[c]);
      seam_load_mn_[c] += step;
      added += step;
    }
    seam_pull_before_mn_[c] = pull;
  }
  double node_force = 0.0;
  for (int c = begin; c < end; ++c) {
    if (held > 0 && subs_[copies_[c].sub].engine->holds_node(copies_[c].local)) {
      seam_load_mn_[c] -= added / held;
    }
    // The pull that keeps a sub-volume awake: the whole load the seam puts on the copy, remembered
    // and sprung (a region that has relaxed carries none, and sleeps).
    node_force = std::max(node_force, (seam_load_mn_[c] + seam_pull_before_mn_[c]).norm());
  }
  seam_gap_mm_[g] =
      widest_gap_mm(count, [&](int i) -> const Eigen::Vector3d& { return at_hand[i]; });
  seam_force_mn_[g] = node_force;
}

double StitchedVolume::widest_copy_gap_mm(int g) const {
  const int begin = copies_begin_[g];
  return widest_gap_mm(copies_begin_[g + 1] - begin, [&](int i) -> const Eigen::Vector3d& {
    return copy_positions_mm_[begin + i];
  });
}

int StitchedVolume::seam_task_count() const {
  return jobs_ != nullptr ? 2 * jobs_->thread_count() : 1;
}

void StitchedVolume::finish_frame(SeamLoads loads) {
  // On the job system: the large case's frame spent 0.8 ms here on one thread. A seam none of
  // whose copies moved keeps last frame's midpoint, gap and pull (on the large case most seams
  // lie between sleeping sub-volumes; fixed seam nodes never move, their midpoints set once).
  moved_subs_.clear();
  for (int s = 0; s < sub_volume_count(); ++s) {
    if (subs_[s].moved) moved_subs_.push_back(s);
  }
  hal::parallel_for(jobs_, static_cast<int>(moved_subs_.size()), [&](int i) {
    SubVolume& sub = subs_[moved_subs_[i]];
    const auto x = sub.engine->deformed_positions_mm();
    for (auto& b : sub.block_bounds) b.setEmpty();
    double motion_squared = 0.0;
    for (std::size_t l = 0; l < x.size(); ++l) {
      sub.block_bounds[sub.node_block[l]].extend(x[l]);
      motion_squared =
          std::max(motion_squared, (x[l] - sub.previous_positions_mm[l]).squaredNorm());
      const int g = sub.global_node[l];
      if (copies_begin_[g + 1] == copies_begin_[g]) {
        shown_[g] = x[l];  // a node of this sub-volume alone
        u_.segment<3>(3 * g) = x[l] - mesh_.rest_positions_mm[g];
      }
    }
    for (std::size_t b = 0; b < sub.block_bounds.size(); ++b) {
      sub.block_center_mm[b] = sub.block_bounds[b].center();
      sub.block_half_diagonal_mm[b] = 0.5 * sub.block_bounds[b].diagonal().norm();
    }
    sub.last_motion_mm = std::sqrt(motion_squared);
  });
  seams_to_update_.clear();
  for_each_moved_seam_node([](const SubVolume&, int) { return true; },
                           [this](int g) { seams_to_update_.push_back(g); });
  const auto seams = static_cast<int>(seams_to_update_.size());
  const int seam_tasks = seam_task_count();
  hal::parallel_for(jobs_, seam_tasks, [&](int task) {
    const int begin = static_cast<int>(static_cast<long>(seams) * task / seam_tasks);
    const int end = static_cast<int>(static_cast<long>(seams) * (task + 1) / seam_tasks);
    for (int i = begin; i < end; ++i) update_seam(seams_to_update_[i], loads);
  });
  // Every side of a seam feels its strongest pull: where three copies agree and the fourth does
  // not, the three must wake too, or the fourth is held deformed by sleepers for ever. Only the
  // sub-volumes with a seam node updated: the others' strongest pull and widest gap are as they
  // were.
  std::fill(holds_updated_seam_.begin(), holds_updated_seam_.end(), 0);
  for (const int g : seams_to_update_) {
    for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
      holds_updated_seam_[copies_[c].sub] = 1;
    }
  }
  hal::parallel_for(jobs_, sub_volume_count(), [&](int s) {
    SubVolume& sub = subs_[s];
    if (!holds_updated_seam_[s]) return;
    sub.max_seam_force_mn = 0.0;
    sub.max_seam_gap_mm = 0.0;
    for (const int local : sub.shared_local) {
      const int g = sub.global_node[local];
      sub.max_seam_force_mn = std::max(sub.max_seam_force_mn, seam_force_mn_[g]);
      sub.max_seam_gap_mm = std::max(sub.max_seam_gap_mm, seam_gap_mm_[g]);
    }
  });
  stats_.max_gap_mm = 0.0;
  stats_.max_seam_force_mn = 0.0;
  for (const auto& sub : subs_) {
    stats_.max_gap_mm = std::max(stats_.max_gap_mm, sub.max_seam_gap_mm);
    stats_.max_seam_force_mn = std::max(stats_.max_seam_force_mn, sub.max_seam_force_mn);
  }
  stats_.sub_volumes_asleep = 0;
  for (auto& sub : subs_) {
    sub.frames_waiting = sub.stepped ? 0 : sub.frames_waiting + 1;
    if (sub.stepped && sub.corotational != nullptr && sub.corotational->warped_system_updated()) {
      sub.times_update_waited = 0;
    }
    if (settings_.selective && !sub.touched && sub.max_seam_force_mn < settings_.sleep_force_mn &&
        sub.last_motion_mm < settings_.sleep_motion_mm) {
      sub.asleep = true;
    } else if (sub.max_seam_force_mn >= settings_.sleep_force_mn) {
      sub.asleep = false;  // a seam pulls: wake
    }
    stats_.sub_volumes_asleep += sub.asleep;
  }
}

void StitchedVolume::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != u_.size()) {
    throw std::invalid_argument("StitchedVolume::set_displacements_mm: expected " +
                                std::to_string(u_.size()) + " values, got " +
                                std::to_string(u_mm.size()));
  }
  // Copies put alike carry no load between them.
  std::fill(seam_load_mn_.begin(), seam_load_mn_.end(), Eigen::Vector3d::Zero());
  std::fill(step_next_.begin(), step_next_.end(), 0);
  std::fill(seam_pull_before_mn_.begin(), seam_pull_before_mn_.end(), Eigen::Vector3d::Zero());
  for (auto& sub : subs_) {
    Eigen::VectorXd local(3 * static_cast<Eigen::Index>(sub.global_node.size()));
    for (std::size_t l = 0; l < sub.global_node.size(); ++l) {
      local.segment<3>(3 * static_cast<Eigen::Index>(l)) = u_mm.segment<3>(3 * sub.global_node[l]);
    }
    sub.engine->set_displacements_mm(local);
    take_positions(sub);
    const auto x = sub.positions_mm;
    std::copy(x.begin(), x.end(), sub.previous_positions_mm.begin());
    sub.asleep = false;
    sub.stepped = sub.moved = true;
  }
  if (coarse_) {
    for (int s = 0; s < sub_volume_count(); ++s) coarse_->update(s, *subs_[s].engine);
  }
  finish_frame(SeamLoads::kKeep);
  for (auto& sub : subs_) {
    sub.stepped = sub.moved = false;
    sub.asleep = false;
  }
  stats_.updates_held = 0;
}

}  // namespace ultrasim::sim
