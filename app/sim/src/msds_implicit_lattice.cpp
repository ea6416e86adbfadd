#include "msds_implicit_lattice.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "msds_spring_lattice.hpp"

namespace ultrasim::sim::msds_detail {

namespace {

void assign_zero(std::vector<double>& v, int size) {
  v.assign(static_cast<std::size_t>(size), 0.0);
}

void size_state(auto& state, int size) {
  for (auto* v :
       {&state.dir_x, &state.dir_y, &state.dir_z, &state.elastic, &state.along, &state.across}) {
    assign_zero(*v, size);
  }
}

}  // namespace

ImplicitLattice::ImplicitLattice(std::span<const Eigen::Vector3d> rest_positions_mm,
                                 std::span<const MsdsSpring> springs,
                                 const ImplicitKernels& kernels,
                                 const ImplicitVectorKernels& vector_kernels)
    : kernels_(kernels),
      vector_kernels_(vector_kernels),
      node_count_(static_cast<int>(rest_positions_mm.size())),
      rest_(rest_positions_mm.begin(), rest_positions_mm.end()) {
  build_diagonals(springs);
  build_loose_springs(springs);
  product_scratch_.resize(static_cast<std::size_t>(range_count()));
  for (auto& scratch : product_scratch_) {
    assign_zero(scratch, 3 * (kNodesPerRange + front_padding_));  // the largest offset
  }
}

int ImplicitLattice::range_count() const {
  return std::max(1, (node_count_ + kNodesPerRange - 1) / kNodesPerRange);
}

int ImplicitLattice::range_end(int range) const {
  return std::min(node_count_, (range + 1) * kNodesPerRange);
}

void ImplicitLattice::build_diagonals(std::span<const MsdsSpring> springs) {
  const std::vector<int> offsets = dense_diagonal_offsets(springs, node_count_);
  front_padding_ = offsets.empty() ? 0 : offsets.back();
  std::map<int, std::size_t> diagonal_of_offset;
  for (const int offset : offsets) {
    const int slots = node_count_ - offset;
    diagonal_of_offset[offset] = diagonals_.size();
    Diagonal d;
    d.offset = offset;
    d.slot_count = slots;
    assign_zero(d.stiffness, slots);
    assign_zero(d.damping, slots);
    assign_zero(d.rest_length, slots);
    // Zero slots on both sides: node_sums reads slot i − offset of node i ≥ 0 and slot i of
    // node i < node_count + kImplicitSumLanes.
    size_state(d.state, front_padding_ + slots + offset + kImplicitSumLanes);
    diagonals_.push_back(std::move(d));
  }
  for (const auto& s : springs) {
    const auto it = diagonal_of_offset.find(s.b - s.a);
    if (it == diagonal_of_offset.end()) continue;
    Diagonal& d = diagonals_[it->second];
    d.stiffness[s.a] = s.stiffness_mn_per_mm;
    d.damping[s.a] = s.damping_mn_s_per_mm;
    d.rest_length[s.a] = s.rest_length_mm;
  }
  // The slots' pointers once every vector is where it stays.
  for (Diagonal& d : diagonals_) {
    SlotState& st = d.state;
    const int at = front_padding_;  // slot 0
    d.slots = {d.offset,
               d.stiffness.data(),
               d.damping.data(),
               d.rest_length.data(),
               st.dir_x.data() + at,
               st.dir_y.data() + at,
               st.dir_z.data() + at,
               st.elastic.data() + at,
               st.along.data() + at,
               st.across.data() + at};
    slots_.push_back(d.slots);
  }
}

void ImplicitLattice::build_loose_springs(std::span<const MsdsSpring> springs) {
  for (const auto& s : springs) {
    const bool on_diagonal = std::any_of(diagonals_.begin(), diagonals_.end(),
                                         [&](const Diagonal& d) { return d.offset == s.b - s.a; });
    if (!on_diagonal) {
      loose_.push_back({s.a, s.b, s.stiffness_mn_per_mm, s.damping_mn_s_per_mm, s.rest_length_mm});
    }
  }
  std::stable_sort(loose_.begin(), loose_.end(),
                   [](const LooseSpring& l, const LooseSpring& r) { return l.a < r.a; });
  size_state(loose_state_, static_cast<int>(loose_.size()));
  loose_of_range_.resize(static_cast<std::size_t>(range_count() + 1));
  for (int r = 0; r <= range_count(); ++r) {
    const int first_node = std::min(node_count_, r * kNodesPerRange);
    loose_of_range_[r] = static_cast<int>(
        std::partition_point(loose_.begin(), loose_.end(),
                             [&](const LooseSpring& l) { return l.a < first_node; }) -
        loose_.begin());
  }
  loose_begin_.assign(static_cast<std::size_t>(node_count_ + 1), 0);
  for (const auto& l : loose_) {
    ++loose_begin_[l.a + 1];
    ++loose_begin_[l.b + 1];
  }
  for (int i = 0; i < node_count_; ++i) loose_begin_[i + 1] += loose_begin_[i];
  loose_index_.resize(static_cast<std::size_t>(loose_begin_[node_count_]));
  loose_sign_.resize(loose_index_.size());
  std::vector<int> fill(loose_begin_.begin(), loose_begin_.end() - 1);
  for (int s = 0; s < static_cast<int>(loose_.size()); ++s) {
    const int at_a = fill[loose_[s].a]++;
    loose_index_[at_a] = s;
    loose_sign_[at_a] = 1.0;
    const int at_b = fill[loose_[s].b]++;
    loose_index_[at_b] = s;
    loose_sign_[at_b] = -1.0;
  }
}

void ImplicitLattice::compute_one(int a, int b, double stiffness, double damping,
                                  double rest_length, NodeArrays position, double h, double& dir_x,
                                  double& dir_y, double& dir_z, double& elastic, double& along,
                                  double& across) const {
  const double dx = position.x[b] - position.x[a];
  const double dy = position.y[b] - position.y[a];
  const double dz = position.z[b] - position.z[a];
  const double length = std::sqrt((dx * dx + dy * dy) + dz * dz);
  Eigen::Vector3d n;
  double transverse = 0.0;  // collapsed: none
  if (length > kImplicitCollapsedFraction * rest_length) {
    const double inverse = 1.0 / length;
    n = {dx * inverse, dy * inverse, dz * inverse};
    const double stretched = 1.0 - rest_length * inverse;
    transverse = stretched > 0.0 ? stretched : 0.0;
  } else {
    // Collapsed (or not finite): pushed apart along the rest direction.
    n = (rest_[b] - rest_[a]) / rest_length;
  }
  const double kh = h * h * stiffness;
  dir_x = n.x();
  dir_y = n.y();
  dir_z = n.z();
  elastic = stiffness * (length - rest_length);
  along = h * damping + kh * (1.0 - transverse);
  across = kh * transverse;
}

void ImplicitLattice::settle_collapsed(Diagonal& d, NodeArrays position, double h, int first,
                                       int last) {
  for (int j = first; j < last; ++j) {
    if (!(d.stiffness[j] > 0.0)) continue;
    const int b = j + d.offset;
    const double dx = position.x[b] - position.x[j];
    const double dy = position.y[b] - position.y[j];
    const double dz = position.z[b] - position.z[j];
    if (std::sqrt((dx * dx + dy * dy) + dz * dz) > kImplicitCollapsedFraction * d.rest_length[j]) {
      continue;
    }
    const ImplicitSlots& sl = d.slots;
    compute_one(j, b, d.stiffness[j], d.damping[j], d.rest_length[j], position, h, sl.dir_x[j],
                sl.dir_y[j], sl.dir_z[j], sl.elastic[j], sl.along[j], sl.across[j]);
  }
}

void ImplicitLattice::compute_springs(int range, NodeArrays position, double h) {
  const int begin = range_begin(range);
  const int end = range_end(range);
  for (Diagonal& d : diagonals_) {
    const int last = std::min(end, d.slot_count);
    if (begin >= last) continue;
    if (kernels_.springs(position, d.slots, h, begin, last)) {
      settle_collapsed(d, position, h, begin, last);  // rare
    }
  }
  SlotState& st = loose_state_;
  for (int s = loose_of_range_[range]; s < loose_of_range_[range + 1]; ++s) {
    const LooseSpring& l = loose_[s];
    compute_one(l.a, l.b, l.stiffness, l.damping, l.rest_length, position, h, st.dir_x[s],
                st.dir_y[s], st.dir_z[s], st.elastic[s], st.along[s], st.across[s]);
  }
}

void ImplicitLattice::sum_node_forces(int begin, int end, MutableNodeArrays elastic,
                                      MutableNodeArrays block_diagonal) const {
  kernels_.node_sums(slots_.data(), static_cast<int>(slots_.size()), begin, end, elastic,
                     block_diagonal);
  if (loose_.empty()) return;
  const SlotState& st = loose_state_;
  for (int i = begin; i < end; ++i) {
    for (int e = loose_begin_[i]; e < loose_begin_[i + 1]; ++e) {
      const int s = loose_index_[e];
      const double f = loose_sign_[e] * st.elastic[s];
      elastic.x[i] += f * st.dir_x[s];
      elastic.y[i] += f * st.dir_y[s];
      elastic.z[i] += f * st.dir_z[s];
      block_diagonal.x[i] += st.along[s] * (st.dir_x[s] * st.dir_x[s]) + st.across[s];
      block_diagonal.y[i] += st.along[s] * (st.dir_y[s] * st.dir_y[s]) + st.across[s];
      block_diagonal.z[i] += st.along[s] * (st.dir_z[s] * st.dir_z[s]) + st.across[s];
    }
  }
}

Eigen::Vector3d ImplicitLattice::damping_force_on(int node, NodeArrays velocity) const {
  // c (Δv · n) n on the spring's a, Δv = v_b − v_a; the opposite on b.
  const auto along_spring = [&](int a, int b, double damping, double nx, double ny,
                                double nz) -> Eigen::Vector3d {
    const double relative_speed =
        ((velocity.x[b] - velocity.x[a]) * nx + (velocity.y[b] - velocity.y[a]) * ny) +
        (velocity.z[b] - velocity.z[a]) * nz;
    return Eigen::Vector3d(nx, ny, nz) * (damping * relative_speed);
  };
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Diagonal& d : diagonals_) {
    const ImplicitSlots& s = d.slots;
    if (node < d.slot_count && d.damping[node] > 0.0) {
      sum += along_spring(node, node + d.offset, d.damping[node], s.dir_x[node], s.dir_y[node],
                          s.dir_z[node]);
    }
    const int below = node - d.offset;
    if (below >= 0 && d.damping[below] > 0.0) {
      sum -= along_spring(below, node, d.damping[below], s.dir_x[below], s.dir_y[below],
                          s.dir_z[below]);
    }
  }
  const SlotState& st = loose_state_;
  for (int e = loose_begin_[node]; e < loose_begin_[node + 1]; ++e) {
    const int s = loose_index_[e];
    const LooseSpring& l = loose_[s];
    sum +=
        loose_sign_[e] * along_spring(l.a, l.b, l.damping, st.dir_x[s], st.dir_y[s], st.dir_z[s]);
  }
  return sum;
}

void ImplicitLattice::multiply(int range, const double* diagonal, NodeArrays p,
                               MutableNodeArrays q) {
  const int begin = range_begin(range);
  const int end = range_end(range);
  for (int i = begin; i < end; ++i) {
    q.x[i] = diagonal[i] * p.x[i];
    q.y[i] = diagonal[i] * p.y[i];
    q.z[i] = diagonal[i] * p.z[i];
  }
  std::vector<double>& scratch = product_scratch_[range];
  const std::size_t third = scratch.size() / 3;
  const MutableNodeArrays product{scratch.data(), scratch.data() + third,
                                  scratch.data() + 2 * third};
  for (const Diagonal& d : diagonals_) {
    kernels_.multiply(d.slots, d.slot_count, p, begin, end, product, q);
  }
  if (loose_.empty()) return;
  const SlotState& st = loose_state_;
  for (int i = begin; i < end; ++i) {
    for (int e = loose_begin_[i]; e < loose_begin_[i + 1]; ++e) {
      const int s = loose_index_[e];
      const LooseSpring& l = loose_[s];
      const int other = l.a == i ? l.b : l.a;
      const double dx = p.x[i] - p.x[other];
      const double dy = p.y[i] - p.y[other];
      const double dz = p.z[i] - p.z[other];
      const double projected =
          st.along[s] * ((st.dir_x[s] * dx + st.dir_y[s] * dy) + st.dir_z[s] * dz);
      q.x[i] += projected * st.dir_x[s] + st.across[s] * dx;
      q.y[i] += projected * st.dir_y[s] + st.across[s] * dy;
      q.z[i] += projected * st.dir_z[s] + st.across[s] * dz;
    }
  }
}

}  // namespace ultrasim::sim::msds_detail
