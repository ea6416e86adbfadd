// StitchedVolume's verdict on a frame: refused (a sub-volume refused, a seam tore), reverted or
// cut back along its update.

#include <algorithm>
#include <cmath>

#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

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

EngineStepStats StitchedVolume::settle_frame(std::span<const int> stepped, int in_reach,
                                             bool deferred, const StepBudget& may_continue) {
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
  // A sub-volume that kept its last good shape only because the budget ran out before smaller
  // steps were tried gives no verdict: as for one piece, the next frame tries again.
  const bool out_of_time = refused && std::ranges::any_of(stepped, [this](int s) {
                             const EngineStepStats& stats = subs_[s].last_stats;
                             return stats.recovery == Recovery::kKeptLastGood && stats.cut_short;
                           });
  // Refused with nothing in reach and no part of it kept, the next frame is this one again (the
  // loads halved at most): the tissue stayed where the probe left it, for good (refuse_gap_mm
  // 0.01: a released press held 2.4 mm deep, every frame refused). With nothing on it the
  // tissue's equilibrium is rest, and the region goes there.
  const bool to_rest = refused && in_reach == 0 && !out_of_time;
  // A sub-volume marked to step has, once its frame is kept; the marks of a frame cut back came
  // from tears its kept part does not have.
  for (int s = 0; s < sub_volume_count(); ++s) {
    if (cut_back || (!refused && subs_[s].stepped)) step_next_[s] = 0;
  }
  // A refused frame with the probe in reach is tried again at another pose (the session's
  // RefusedPress); one with nothing in reach, out of time, again with its loads halved (put to
  // rest, the seams carry none). A frame cut back is the tissue springing back with nothing in
  // reach: the loads are released as for a refusal, else they keep a seam they opened at the bound.
  const SeamLoads loads = settings_.seam_load_rate <= 0.0 || to_rest ? SeamLoads::kKeep
                          : cut_back                                 ? SeamLoads::kHalve
                          : !refused                                 ? SeamLoads::kRemember
                          : in_reach == 0                            ? SeamLoads::kHalve
                                                                     : SeamLoads::kKeep;
  if (to_rest) {
    place_sub_volumes(nullptr);  // every sub-volume's coarse residual with it
  } else if (refused) {
    revert_frame(stepped);
  } else {
    join_held_copies();
    correct_finely(may_continue);
  }
  if (!to_rest) update_coarse_residuals(stepped);
  EngineStepStats out = stepped_stats();
  // Deferred sub-volumes, or a stepped one's solve stopped by the budget.
  out.cut_short = out.cut_short || deferred;
  if (cut_back) {
    out.diverged = true;
    out.cause = DivergenceCause::kSeamTorn;
    out.recovery = worse_recovery(out.recovery, Recovery::kSubstepped);
  }
  if (refused) {
    // One piece's verdict on the press (the session then holds the probe where the tissue last
    // took it), not a frame left unfinished unless out of time; or the region put to rest.
    out.diverged = true;
    out.cause = refusal;
    out.recovery = to_rest ? Recovery::kReset : Recovery::kKeptLastGood;
    out.cut_short = out_of_time;
  }
  finish_frame(loads);
  return out;
}

EngineStepStats StitchedVolume::stepped_stats() const {
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
  return out;
}

}  // namespace ultrasim::sim
