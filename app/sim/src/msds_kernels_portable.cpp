// The portable kernels (msds_kernels.hpp): std::experimental::simd at the build's native width.

#include <cmath>
#include <experimental/simd>
#include <limits>

#include "msds_kernels.hpp"

namespace ultrasim::sim::msds_detail {

namespace {

namespace stdx = std::experimental;

using Floats = stdx::native_simd<float>;
// Four lanes whatever the native width: the kinetic energy is summed in kEnergyLanes partial
// sums, the AVX2 kernel's lanes, so that both give the same rounding.
using Doubles = stdx::fixed_size_simd<double, kEnergyLanes>;
constexpr int kFloatLanes = static_cast<int>(Floats::size());
constexpr int kDoubleLanes = static_cast<int>(Doubles::size());
static_assert(kFloatLanes <= kNodePadding && kDoubleLanes <= kNodePadding);

// Forced inline: -O2 would call these and pass SIMD values through memory.
[[gnu::always_inline]] inline Floats load(const float* p) {
  return Floats(p, stdx::element_aligned);
}

[[gnu::always_inline]] inline Doubles load_double(const double* p) {
  return Doubles(p, stdx::element_aligned);
}

[[gnu::always_inline]] inline Doubles load_double(const float* p) {
  return Doubles(p, stdx::element_aligned);  // converts
}

[[gnu::always_inline]] inline void store(const Floats& v, float* p) {
  v.copy_to(p, stdx::element_aligned);
}

// b − a of the nodes j.. and j + offset.. of one coordinate.
[[gnu::always_inline]] inline Floats difference(const float* a, int j, int offset) {
  return load(a + j + offset) - load(a + j);
}

bool slot_forces(const FloatNodeState& s, const DiagonalSlots& d, float damping_per_stiffness_s,
                 int first, int last) {
  const int o = d.offset;
  Floats::mask_type collapsed(false);
  for (int j = first; j < last; j += kFloatLanes) {
    const Floats dx = difference(s.x.data(), j, o);
    const Floats dy = difference(s.y.data(), j, o);
    const Floats dz = difference(s.z.data(), j, o);
    const Floats length = stdx::sqrt(dx * dx + dy * dy + dz * dz);
    const Floats k = load(d.stiffness + j);
    const Floats rest_length = load(d.rest_length + j);
    const auto regular = length > kCollapsedFraction * rest_length;
    collapsed = collapsed || (k > 0.0f && !regular);
    // Empty slots (k = 0) give 0, and so do collapsed lanes: 1/l is zeroed there (coincident
    // nodes with no spring between them would give 0 × ∞).
    Floats inverse_length = 1.0f / length;
    stdx::where(!regular, inverse_length) = 0.0f;
    const Floats ux = dx * inverse_length, uy = dy * inverse_length, uz = dz * inverse_length;
    const Floats relative_speed = difference(s.vx.data(), j, o) * ux +
                                  difference(s.vy.data(), j, o) * uy +
                                  difference(s.vz.data(), j, o) * uz;
    const Floats magnitude =
        k * (length - rest_length) + (k * damping_per_stiffness_s) * relative_speed;
    const int at = j - d.first_slot;
    store(magnitude * ux, d.force_x + at);
    store(magnitude * uy, d.force_y + at);
    store(magnitude * uz, d.force_z + at);
  }
  return stdx::any_of(collapsed);
}

void node_sums(std::span<const DiagonalSlots> diagonals, int begin, int end, float* f_x, float* f_y,
               float* f_z) {
  // Diagonal by diagonal into the sums (each diagonal's pointers loaded once), from +0.
  const int count = end - begin;
  for (int i = 0; i < count; i += kFloatLanes) {
    store(Floats(0.0f), f_x + i);
    store(Floats(0.0f), f_y + i);
    store(Floats(0.0f), f_z + i);
  }
  for (const DiagonalSlots& d : diagonals) {
    const float *const force_x = d.force_x, *const force_y = d.force_y, *const force_z = d.force_z;
    const int as_a = begin - d.first_slot;  // node begin's slot as a, in the buffers
    const int as_b = as_a - d.offset;       // and as b
    for (int i = 0; i < count; i += kFloatLanes) {
      store(load(f_x + i) + (load(force_x + as_a + i) - load(force_x + as_b + i)), f_x + i);
      store(load(f_y + i) + (load(force_y + as_a + i) - load(force_y + as_b + i)), f_y + i);
      store(load(f_z + i) + (load(force_z + as_a + i) - load(force_z + as_b + i)), f_z + i);
    }
  }
}

// One coordinate of forward Euler on lanes i..; returns the new velocity.
[[gnu::always_inline]] inline Doubles advance(double* x, double* v, const float* f, int i, int at,
                                              double dt_s, const Doubles& step_per_force,
                                              float* next_x, float* next_v, Doubles& travel,
                                              Doubles& not_finite) {
  const Doubles x_old = load_double(x + i), v_old = load_double(v + i);
  const Doubles x_new = x_old + dt_s * v_old;
  const Doubles v_new = v_old + step_per_force * load_double(f + at);
  travel += stdx::abs(v_old);
  not_finite += x_new - x_new;
  x_new.copy_to(x + i, stdx::element_aligned);
  v_new.copy_to(v + i, stdx::element_aligned);
  x_new.copy_to(next_x + i, stdx::element_aligned);
  v_new.copy_to(next_v + i, stdx::element_aligned);
  return v_new;
}

NodeUpdateSums forward_euler(const ExplicitNodeArrays& n, int begin, int end, double dt_s,
                             const float* f_x, const float* f_y, const float* f_z,
                             FloatNodeState& next) {
  Doubles kinetic = 0.0;
  // x − x is 0 for a finite x and NaN otherwise; velocities show in the kinetic energy.
  Doubles not_finite = 0.0;
  Doubles min_clearance = std::numeric_limits<double>::infinity();
  for (int i = begin; i < end; i += kDoubleLanes) {
    const Doubles step_per_force = dt_s * load_double(n.inverse_mass_per_kg + i);
    const int at = i - begin;
    Doubles travel = 0.0;
    const Doubles vx = advance(n.x, n.vx, f_x, i, at, dt_s, step_per_force, next.x.data(),
                               next.vx.data(), travel, not_finite);
    const Doubles vy = advance(n.y, n.vy, f_y, i, at, dt_s, step_per_force, next.y.data(),
                               next.vy.data(), travel, not_finite);
    const Doubles vz = advance(n.z, n.vz, f_z, i, at, dt_s, step_per_force, next.z.data(),
                               next.vz.data(), travel, not_finite);
    const Doubles clearance = load_double(n.probe_clearance_mm + i) - dt_s * travel;
    clearance.copy_to(n.probe_clearance_mm + i, stdx::element_aligned);
    min_clearance = stdx::min(min_clearance, clearance);
    kinetic += 0.5 * load_double(n.mass_kg + i) * (vx * vx + vy * vy + vz * vz);
  }
  NodeUpdateSums sums;
  sums.kinetic_energy_uj = (kinetic[0] + kinetic[1]) + (kinetic[2] + kinetic[3]);
  sums.finite = stdx::all_of(not_finite == 0.0) && std::isfinite(sums.kinetic_energy_uj);
  sums.min_probe_clearance_mm = stdx::hmin(min_clearance);
  return sums;
}

}  // namespace

void FloatNodeState::assign_zero(int node_count) {
  for (auto* a : {&x, &y, &z, &vx, &vy, &vz}) {
    a->assign(static_cast<std::size_t>(node_count + kNodePadding), 0.0f);
  }
}

void FloatNodeState::set(int node, const Eigen::Vector3d& position_mm,
                         const Eigen::Vector3d& velocity_mm_per_s) {
  x[node] = static_cast<float>(position_mm.x());
  y[node] = static_cast<float>(position_mm.y());
  z[node] = static_cast<float>(position_mm.z());
  vx[node] = static_cast<float>(velocity_mm_per_s.x());
  vy[node] = static_cast<float>(velocity_mm_per_s.y());
  vz[node] = static_cast<float>(velocity_mm_per_s.z());
}

SpringKernels portable_kernels() {
  return {&slot_forces, &node_sums, &forward_euler};
}

}  // namespace ultrasim::sim::msds_detail
