// StitchedVolume's selection: which sub-volumes a frame steps, in what order and batches.

#include <algorithm>

#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

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

}  // namespace ultrasim::sim
