#include "msds_spring_lattice.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace ultrasim::sim::msds_detail {

namespace {

Eigen::Vector3f difference(const FloatNodeState& s, int from, int to) {
  return {s.x[to] - s.x[from], s.y[to] - s.y[from], s.z[to] - s.z[from]};
}

// The kernels' length of a spring vector: the same operations in the same order.
float length_of(const Eigen::Vector3f& d) {
  return std::sqrt((d.x() * d.x() + d.y() * d.y()) + d.z() * d.z());
}

}  // namespace

SpringLattice::SpringLattice(std::span<const Eigen::Vector3d> rest_positions_mm,
                             std::span<const MsdsSpring> springs, double damping_per_stiffness_s,
                             const SpringKernels& kernels)
    : kernels_(kernels),
      node_count_(static_cast<int>(rest_positions_mm.size())),
      damping_per_stiffness_s_(static_cast<float>(damping_per_stiffness_s)) {
  rest_.assign_zero(node_count_);
  for (int i = 0; i < node_count_; ++i) {
    rest_.set(i, rest_positions_mm[i], Eigen::Vector3d::Zero());
  }
  build_diagonals(springs);
  build_loose_springs(springs);
}

std::vector<int> dense_diagonal_offsets(std::span<const MsdsSpring> springs, int node_count) {
  std::map<int, int> springs_per_offset;
  for (const auto& s : springs) ++springs_per_offset[s.b - s.a];
  std::vector<int> offsets;
  for (const auto& [offset, count] : springs_per_offset) {
    if (count >= kMinDiagonalFill * (node_count - offset)) offsets.push_back(offset);
  }
  return offsets;
}

void SpringLattice::build_diagonals(std::span<const MsdsSpring> springs) {
  std::map<int, std::size_t> diagonal_of_offset;
  for (const int offset : dense_diagonal_offsets(springs, node_count_)) {
    const int slots = node_count_ - offset;
    diagonal_of_offset[offset] = diagonals_.size();
    Diagonal d;
    d.offset = offset;
    d.slot_count = slots;
    d.stiffness.assign(static_cast<std::size_t>(slots + kNodePadding), 0.0f);
    d.rest_length.assign(d.stiffness.size(), 0.0f);
    diagonals_.push_back(std::move(d));
  }
  for (const auto& s : springs) {
    const auto it = diagonal_of_offset.find(s.b - s.a);
    if (it == diagonal_of_offset.end()) continue;
    Diagonal& d = diagonals_[it->second];
    d.stiffness[s.a] = static_cast<float>(s.stiffness_mn_per_mm);
    d.rest_length[s.a] = length_of(difference(rest_, s.a, s.b));
  }
}

void SpringLattice::build_loose_springs(std::span<const MsdsSpring> springs) {
  std::vector<const MsdsSpring*> loose;
  for (const auto& s : springs) {
    const bool on_diagonal = std::any_of(diagonals_.begin(), diagonals_.end(),
                                         [&](const Diagonal& d) { return d.offset == s.b - s.a; });
    if (!on_diagonal) loose.push_back(&s);
  }
  loose_begin_.assign(static_cast<std::size_t>(node_count_ + 1), 0);
  for (const auto* s : loose) {
    ++loose_begin_[s->a + 1];
    ++loose_begin_[s->b + 1];
  }
  for (int i = 0; i < node_count_; ++i) loose_begin_[i + 1] += loose_begin_[i];
  const auto entries = static_cast<std::size_t>(loose_begin_[node_count_]);
  loose_other_.resize(entries);
  loose_stiffness_.resize(entries);
  loose_rest_length_.resize(entries);
  std::vector<int> fill(loose_begin_.begin(), loose_begin_.end() - 1);
  for (const auto* s : loose) {
    const float k = static_cast<float>(s->stiffness_mn_per_mm);
    const float rest_length = length_of(difference(rest_, s->a, s->b));
    for (const auto& [node, other] : {std::pair{s->a, s->b}, std::pair{s->b, s->a}}) {
      const int e = fill[node]++;
      loose_other_[e] = other;
      loose_stiffness_[e] = k;
      loose_rest_length_[e] = rest_length;
    }
  }
}

SpringLattice::Sweep SpringLattice::make_sweep(int begin, int end) const {
  Sweep sweep;
  sweep.begin_ = begin;
  sweep.end_ = end;
  for (const Diagonal& d : diagonals_) {
    DiagonalSlots slots;
    slots.offset = d.offset;
    slots.stiffness = d.stiffness.data();
    slots.rest_length = d.rest_length.data();
    slots.first_slot = begin - d.offset;
    const auto size = static_cast<std::size_t>(end + kNodePadding - slots.first_slot);
    for (int axis = 0; axis < 3; ++axis) sweep.buffers_.emplace_back(size, 0.0f);
    const auto buffer = sweep.buffers_.end() - 3;
    slots.force_x = buffer[0].data();
    slots.force_y = buffer[1].data();
    slots.force_z = buffer[2].data();
    sweep.slots_.push_back(slots);
  }
  return sweep;
}

void SpringLattice::start_sweep(Sweep& sweep, const FloatNodeState& state) const {
  for (std::size_t d = 0; d < diagonals_.size(); ++d) {
    const int first = std::max(0, sweep.begin_ - diagonals_[d].offset);
    const int last = std::min(sweep.begin_, diagonals_[d].slot_count);
    if (first < last) compute_slots(static_cast<int>(d), sweep.slots_[d], state, first, last);
  }
}

void SpringLattice::block_forces(Sweep& sweep, const FloatNodeState& state, int block_begin,
                                 int block_end, float* f_x, float* f_y, float* f_z) const {
  // Every diagonal's slots of the block first (the block's nodes are their a) ...
  for (std::size_t d = 0; d < diagonals_.size(); ++d) {
    const int last = std::min(block_end, diagonals_[d].slot_count);
    if (block_begin < last) {
      compute_slots(static_cast<int>(d), sweep.slots_[d], state, block_begin, last);
    }
  }
  // ... then each node's sum: + its own slots (it is a), − the slots offset below (it is b).
  kernels_.node_sums(sweep.slots_, block_begin, block_end, f_x, f_y, f_z);
  add_loose_forces(state, block_begin, block_end, f_x, f_y, f_z);
}

void SpringLattice::compute_slots(int d, DiagonalSlots& slots, const FloatNodeState& state,
                                  int first, int last) const {
  if (!kernels_.slot_forces(state, slots, damping_per_stiffness_s_, first, last)) return;
  // Rare: a spring squeezed to (nearly) nothing, left 0 by the kernel.
  const Diagonal& diagonal = diagonals_[d];
  for (int j = first; j < last; ++j) {
    const float k = diagonal.stiffness[j];
    const float rest_length = diagonal.rest_length[j];
    if (!(k > 0.0f) ||
        length_of(difference(state, j, j + diagonal.offset)) > kCollapsedFraction * rest_length) {
      continue;
    }
    const Eigen::Vector3f f = spring_force_on(j, j + diagonal.offset, k, rest_length, state);
    const int at = j - slots.first_slot;
    slots.force_x[at] = f.x();
    slots.force_y[at] = f.y();
    slots.force_z[at] = f.z();
  }
}

Eigen::Vector3f SpringLattice::spring_force_on(int from, int to, float stiffness, float rest_length,
                                               const FloatNodeState& state) const {
  const Eigen::Vector3f d = difference(state, from, to);
  const float length = length_of(d);
  // Collapsed (or not finite): push apart along the rest direction.
  const Eigen::Vector3f dir = length > kCollapsedFraction * rest_length
                                  ? Eigen::Vector3f(d * (1.0f / length))
                                  : Eigen::Vector3f(difference(rest_, from, to) / rest_length);
  const Eigen::Vector3f dv(state.vx[to] - state.vx[from], state.vy[to] - state.vy[from],
                           state.vz[to] - state.vz[from]);
  const float relative_speed = (dv.x() * dir.x() + dv.y() * dir.y()) + dv.z() * dir.z();
  const float magnitude =
      stiffness * (length - rest_length) + (stiffness * damping_per_stiffness_s_) * relative_speed;
  return magnitude * dir;
}

void SpringLattice::add_loose_forces(const FloatNodeState& state, int block_begin, int block_end,
                                     float* f_x, float* f_y, float* f_z) const {
  if (loose_other_.empty()) return;
  for (int i = block_begin; i < block_end; ++i) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int e = loose_begin_[i]; e < loose_begin_[i + 1]; ++e) {
      sum += spring_force_on(i, loose_other_[e], loose_stiffness_[e], loose_rest_length_[e], state);
    }
    f_x[i - block_begin] += sum.x();
    f_y[i - block_begin] += sum.y();
    f_z[i - block_begin] += sum.z();
  }
}

}  // namespace ultrasim::sim::msds_detail
