// StitchedVolume's seams: the copies' anchors, joins, gaps, loads and the shown midpoints.

#include <algorithm>
#include <cmath>

#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

namespace {

// Copies of a seam node the probe holds in several sub-volumes farther apart than this (issue 5's
// gap target) are put at their mean.
constexpr double kJoinHeldCopiesMm = 0.1;

// A seam's remembered loads fade by this fraction a frame where its copies did not all step
// ([stitching] seam_load_rate).
constexpr double kSeamLoadFadePerFrame = 0.1;

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
    const bool lead = seam_lead_ > 0.0 && seam_move_frame_[g] == frames_finished_;
    for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
      if (c == own) continue;
      others += copy_positions_mm_[c];
      if (lead && steps_later_in_exchange_[copies_[c].sub]) {
        others += seam_lead_ * seam_move_per_exchange_mm_[g];
      }
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

void StitchedVolume::update_seam(int g, SeamLoads loads) {
  const int begin = copies_begin_[g], end = copies_begin_[g + 1];
  const int count = end - begin;
  const auto at_hand =
      std::span(copy_positions_mm_)
          .subspan(static_cast<std::size_t>(begin), static_cast<std::size_t>(count));
  const Eigen::Vector3d sum = copies_sum(g);
  int stepped = 0;
  for (int c = begin; c < end; ++c) stepped += subs_[copies_[c].sub].stepped;
  if (seam_lead_ > 0.0 && loads == SeamLoads::kRemember && stepped == count) {
    const Eigen::Vector3d move = (sum / count - shown_[g]) / stats_.exchanges;
    const bool consecutive = seam_move_frame_[g] == frames_finished_;
    Eigen::Vector3d& before = seam_move_before_mm_[g];
    if (!consecutive) before.setZero();
    for (int a = 0; a < 3; ++a) {
      seam_move_per_exchange_mm_[g][a] = move[a] * before[a] <= 0.0 ? 0.0
                                         : move[a] > 0.0            ? std::min(move[a], before[a])
                                                                    : std::max(move[a], before[a]);
    }
    before = move;
    seam_move_frame_[g] = frames_finished_ + 1;  // this frame's, once finish_frame has counted it
  } else {
    seam_move_before_mm_[g].setZero();
  }
  shown_[g] = sum / count;  // the published midpoint: no gap shows
  u_.segment<3>(3 * g) = shown_[g] - mesh_.rest_positions_mm[g];
  if (fixed_[g]) {
    seam_gap_mm_[g] = seam_force_mn_[g] = 0.0;
    return;
  }
  // The springs' pull is added to the loads where every copy stepped this frame: a copy left
  // where it was did not answer the load it was given (with one copy stepped at a time the loads
  // wound up and swung, ±150 mN at a four-copy corner of the large case). Elsewhere the loads
  // fade, so that a region whose copies no longer step together (after the probe has left,
  // one extra sub-volume a frame) is not held deformed by what they last carried. A copy the
  // probe holds does not answer its anchor either (two held apart would wind up for ever): the
  // free copies' change is taken by the held ones between them, and the loads still add up to
  // zero over the node's copies. A frame cut back with nothing in the probe's reach (or refused
  // there for want of time) halves the loads of the seams it went back on: the loads themselves
  // may tear a seam (a press they carried, released at once, opens the seam by load / k), and
  // kept as they were the same frame would be refused for ever (a 2 × 1 split lifted from: 200
  // frames refused, the tissue left pressed 3.8 mm under no probe). Halved under a press too, they
  // gave way to the springs alone frame after frame, and the large soak's refused frames rose
  // (1,954 against 896-1,201).
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

int StitchedVolume::first_moved_copy(int g) const {
  for (int c = copies_begin_[g]; c < copies_begin_[g + 1]; ++c) {
    if (subs_[copies_[c].sub].moved) return c;
  }
  return -1;
}

void StitchedVolume::finish_frame(SeamLoads loads) {
  // On the job system, a task per moved sub-volume: its bounds and motion, its own nodes' shown
  // positions, and the seams of which it holds the first moved copy (each updated once). The
  // large case's frame spent 0.8 ms here on one thread; with the seams to update gathered first,
  // one thread, and their holders marked copy by copy, 0.47-0.66 ms on two. A seam none of whose
  // copies moved keeps last frame's midpoint, gap and pull (on the large case most seams lie
  // between sleeping sub-volumes; fixed seam nodes never move, their midpoints set once).
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
    for (std::size_t k = 0; k < sub.shared_local.size(); ++k) {
      const int g = sub.global_node[sub.shared_local[k]];
      if (first_moved_copy(g) == sub.shared_copy[k]) update_seam(g, loads);
    }
  });
  // Every side of a seam feels its strongest pull: where three copies agree and the fourth does
  // not, the three must wake too, or the fourth is held deformed by sleepers for ever. Only the
  // sub-volumes with a seam node updated (the moved ones and those sharing a node with one): the
  // others' strongest pull and widest gap are as they were.
  std::fill(holds_updated_seam_.begin(), holds_updated_seam_.end(), 0);
  const int count = sub_volume_count();
  for (const int s : moved_subs_) {
    for (int t = 0; t < count; ++t) {
      if (t == s || shared_node_count_[s * count + t] > 0) holds_updated_seam_[t] = 1;
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
  ++frames_finished_;
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

}  // namespace ultrasim::sim
