// StitchedVolume's coarse and fine corrections around the sub-volumes' own steps.

#include <algorithm>

#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

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

}  // namespace ultrasim::sim
