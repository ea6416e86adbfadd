#include "ultrasim/sim/stitched_volume.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "stitched_frame_time.hpp"
#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {

namespace {

std::string sub_name(const SubVolumeBox& box) {
  return "sub-volume (" + std::to_string(box.index.x()) + ", " + std::to_string(box.index.y()) +
         ", " + std::to_string(box.index.z()) + ")";
}

// Nodes per axis of the blocks the reach test bounds (4³ = 64 nodes, a few mm across).
constexpr int kReachBlockNodes = 4;

}  // namespace

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
      fixed_(fixed_nodes.begin(), fixed_nodes.end()),
      frame_time_(std::make_unique<StitchedFrameTime>(budget_mutex_)) {
  if (static_cast<int>(tet_materials.size()) != mesh_.tet_count()) {
    throw std::invalid_argument("StitchedVolume: " + std::to_string(tet_materials.size()) +
                                " materials for " + std::to_string(mesh_.tet_count()) + " tets");
  }
  if (static_cast<int>(fixed_nodes.size()) != mesh_.node_count()) {
    throw std::invalid_argument("StitchedVolume: " + std::to_string(fixed_nodes.size()) +
                                " fixed flags for " + std::to_string(mesh_.node_count()) +
                                " nodes");
  }
  if (!(stitching.spring_stiffness_per_modulus_mm > 0.0) ||
      !(stitching.implicit_msds_spring_stiffness_per_modulus_mm > 0.0)) {
    throw std::invalid_argument(
        "StitchedVolume: spring_stiffness_per_modulus_mm and "
        "implicit_msds_spring_stiffness_per_modulus_mm must be > 0");
  }
  if (!(stitching.implicit_msds_seam_lead >= 0.0 && stitching.implicit_msds_seam_lead <= 1.0)) {
    throw std::invalid_argument("StitchedVolume: implicit_msds_seam_lead must lie in [0, 1]");
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
  for (const auto& [name, exchanges] :
       {std::pair{"explicit_msds_exchanges_per_frame", stitching.explicit_msds_exchanges_per_frame},
        std::pair{"implicit_msds_exchanges_per_frame",
                  stitching.implicit_msds_exchanges_per_frame}}) {
    if (exchanges < 1 || engine_settings.msds.steps_per_frame % exchanges != 0) {
      throw std::invalid_argument("StitchedVolume: " + std::string(name) + " (" +
                                  std::to_string(exchanges) +
                                  ") must be >= 1 and divide the MSDS's steps_per_frame (" +
                                  std::to_string(engine_settings.msds.steps_per_frame) + ")");
    }
  }
  exchanges_per_frame_ =
      method == EngineKind::kMsdsExplicit      ? stitching.explicit_msds_exchanges_per_frame
      : method == EngineKind::kMsdsImplicit    ? stitching.implicit_msds_exchanges_per_frame
      : method == EngineKind::kCorotationalFem ? stitching.corotational_exchanges_per_frame
                                               : stitching.exchanges_per_frame;
  if (method == EngineKind::kMsdsImplicit) seam_lead_ = stitching.implicit_msds_seam_lead;
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
  seam_move_per_exchange_mm_.assign(mesh_.node_count(), Eigen::Vector3d::Zero());
  seam_move_before_mm_.assign(mesh_.node_count(), Eigen::Vector3d::Zero());
  seam_move_frame_.assign(mesh_.node_count(), 0u);
  steps_later_in_exchange_.assign(subs_.size(), 0);
  node_stamp_.assign(mesh_.node_count(), 0u);
  moved_subs_.reserve(subs_.size());
  subs_to_look_at_.reserve(subs_.size());
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
    settings.msds.continue_stopped_steps = false;
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
    sub.msds = dynamic_cast<MsdsEngine*>(sub.engine.get());
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
  const double stiffness_per_modulus_mm =
      method_ == EngineKind::kMsdsImplicit ? settings_.implicit_msds_spring_stiffness_per_modulus_mm
                                           : settings_.spring_stiffness_per_modulus_mm;
  for (int g = 0; g < n; ++g) {
    if (copies_begin_[g + 1] - copies_begin_[g] < 2) continue;
    shared_nodes_.push_back(g);
    seam_stiffness_mn_per_mm_[g] = stiffness_per_modulus_mm * stiffest_kpa[g];
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

void StitchedVolume::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != u_.size()) {
    throw std::invalid_argument("StitchedVolume::set_displacements_mm: expected " +
                                std::to_string(u_.size()) + " values, got " +
                                std::to_string(u_mm.size()));
  }
  place_sub_volumes(&u_mm);
  for (auto& sub : subs_) sub.stepped = true;
  finish_frame(SeamLoads::kKeep);
  for (auto& sub : subs_) {
    sub.stepped = sub.moved = false;
    sub.asleep = false;
  }
  stats_.updates_held = 0;
}

void StitchedVolume::place_sub_volumes(const Eigen::VectorXd* u_mm) {
  // Copies put alike carry no load between them.
  std::fill(seam_load_mn_.begin(), seam_load_mn_.end(), Eigen::Vector3d::Zero());
  std::fill(step_next_.begin(), step_next_.end(), 0);
  std::fill(seam_pull_before_mn_.begin(), seam_pull_before_mn_.end(), Eigen::Vector3d::Zero());
  for (auto& sub : subs_) {
    // revert_mm is the frame verdict's scratch, sized once: placing allocates nothing.
    for (std::size_t l = 0; l < sub.global_node.size(); ++l) {
      sub.revert_mm.segment<3>(3 * static_cast<Eigen::Index>(l)) =
          u_mm != nullptr ? Eigen::Vector3d(u_mm->segment<3>(3 * sub.global_node[l]))
                          : Eigen::Vector3d::Zero();
    }
    sub.engine->set_displacements_mm(sub.revert_mm);
    take_positions(sub);
    const auto x = sub.positions_mm;
    std::copy(x.begin(), x.end(), sub.previous_positions_mm.begin());
    sub.asleep = false;
    sub.moved = true;
  }
  if (coarse_) {
    for (int s = 0; s < sub_volume_count(); ++s) coarse_->update(s, *subs_[s].engine);
  }
}

}  // namespace ultrasim::sim
