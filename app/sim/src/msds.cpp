#include "ultrasim/sim/msds.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "model_checks.hpp"
#include "msds_chunks.hpp"
#include "msds_implicit_lattice.hpp"
#include "msds_kernels.hpp"
#include "msds_spring_lattice.hpp"
#include "msds_task_team.hpp"
#include "msds_tet_lattice.hpp"

namespace ultrasim::sim {

// Stability of the explicit step (forward_euler_stable_time_step_s, msds_max_omega_squared_bound).
//
// Linearised about rest, the MSDS is M ẍ + C ẋ + K x = 0: M the lumped masses, K the springs
// (k n nᵀ between each spring's nodes) and, since every spring has c = β k along the same
// direction n, C = β K exactly (β = damping_per_stiffness_s). M⁻¹K has real eigenvalues ω² ≥ 0
// (it is similar to M^-½ K M^-½) and M⁻¹C shares its eigenvectors, so the system splits into
// modes q̈ + β ω² q̇ + ω² q = 0 with characteristic roots
//   s = (−β ω² ± √(β² ω⁴ − 4 ω²)) / 2.
// Forward Euler on the first-order form (x, v) multiplies each root's component by 1 + dt·s per
// step, so it is stable iff |1 + dt·s| ≤ 1 for every root:
//   β ω ≤ 2 (a complex pair): |1 + dt s|² = 1 − dt β ω² + dt² ω² ≤ 1  ⇔  dt ≤ β;
//   β ω > 2 (two negative reals): the faster root binds, |s| = (β ω² + ω √(β² ω² − 4)) / 2, and
//     1 + dt s ≥ −1  ⇔  dt ≤ 2 / |s| = 4 / (β ω² + ω √(β² ω² − 4))  (≈ 2 / (β ω²) for β ω ≫ 2).
// The branches meet at β ω = 2 (dt = β) and the bound falls as ω grows: the stiffest mode decides.
// Its ω² is bounded by Gershgorin's theorem on the rows of M⁻¹K restricted to the free DOFs:
// every eigenvalue lies in a disc about a diagonal entry whose radius is the rest of the row's
// absolute sum, and the eigenvalues are real and ≥ 0, so ω²_max ≤ the largest absolute row sum.
// For row x of free node i, with n the unit direction of spring s (at rest) and D_i = Σ_s k_s n nᵀ
// its diagonal block:
//   (1/m_i) [ Σ_y |(D_i)_xy| + Σ_{springs s from i to a free node} k_s |n_x| (|n_x|+|n_y|+|n_z|) ].
// (A spring to a pinned node has no off-diagonal block.) Entry-wise rows beat 3×3 blocks here: a
// spring across x adds nothing to row x. The bound is safe (dt_bound ≤ the true limit); on the
// tests' grid meshes it is 1.3–1.4× the true ω²_max, so dt_bound ≈ 0.7× the true limit (the tests
// measure it by bisection).

namespace {

using msds_detail::kNodePadding;

using msds_detail::chunk_count;
using msds_detail::kNodesPerChunk;
// steps × kMaxFrameStretch << kMaxHalvings must fit an int.
constexpr int kMaxStepsPerFrame = 100000;
constexpr int kMaxFrameStretch = 64;
// A node this close to the probe's surface (or inside it) is a contact: a node held on the surface
// last step stays in contact while the probe stays.
constexpr double kTouchToleranceMm = 1e-6;
// A node whose clearance bound is below this is queried: the tolerance, plus as much again for the
// rounding of the bound (each step's is ~1e-14 mm, and a frame's first step resets it).
constexpr double kCandidateReachMm = 2.0 * kTouchToleranceMm;
// A spring shorter than this fraction of its rest length has no reliable direction of its own.
constexpr double kCollapsedFraction = 1e-9;
constexpr double kKgPerMm3PerKgPerM3 = 1e-9;

void require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("MSDS: " + message);
}

bool positive_finite(double value) {
  return value > 0.0 && std::isfinite(value);
}

void check_settings(const MsdsSettings& s) {
  require(positive_finite(s.stiffness_per_modulus_mm), "stiffness_per_modulus_mm must be > 0");
  require(s.damping_per_stiffness_s >= 0.0 && std::isfinite(s.damping_per_stiffness_s),
          "damping_per_stiffness_s must be >= 0");
  require(positive_finite(s.density_kg_per_m3), "density_kg_per_m3 must be > 0");
  require(positive_finite(s.time_step_s), "time_step_s must be > 0");
  require(s.steps_per_frame >= 1 && s.steps_per_frame <= kMaxStepsPerFrame,
          "steps_per_frame must be in [1, " + std::to_string(kMaxStepsPerFrame) + "]");
  require(s.max_inverted_fraction >= 0.0 && s.max_inverted_fraction <= 1.0,
          "max_inverted_fraction must be in [0, 1]");
  require(s.implicit_steps_per_frame >= 1 && s.implicit_steps_per_frame <= kMaxStepsPerFrame,
          "implicit_steps_per_frame must be in [1, " + std::to_string(kMaxStepsPerFrame) + "]");
  check_held_contact_settings(s.contact, "MSDS");
}

}  // namespace

namespace {

// One node's largest absolute row sum of K over its three rows (mN/mm), summed spring by
// spring: Gershgorin's radius about zero for the node's rows of K, so ω² ≤ row / mass. A pinned
// neighbour's columns drop out (its entries are 0).
class GershgorinRow {
 public:
  // A spring's 3 × 3 stiffness block on the node, to a neighbour pinned or not.
  void add(const Eigen::Matrix3d& block, bool neighbour_pinned) {
    diagonal_ += block;
    if (!neighbour_pinned) off_diagonal_row_sums_ += block.cwiseAbs().rowwise().sum();
  }
  double value() const {
    return (diagonal_.cwiseAbs().rowwise().sum() + off_diagonal_row_sums_).maxCoeff();
  }

 private:
  Eigen::Matrix3d diagonal_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d off_diagonal_row_sums_ = Eigen::Vector3d::Zero();
};

// Every node's GershgorinRow at rest (0 on pinned nodes, whose rows drop out).
std::vector<double> gershgorin_row_sums(std::span<const Eigen::Vector3d> rest_positions_mm,
                                        std::span<const MsdsSpring> springs,
                                        std::span<const std::uint8_t> pinned) {
  const std::size_t n = pinned.size();
  std::vector<GershgorinRow> node_rows(n);
  for (const auto& s : springs) {
    const Eigen::Vector3d dir = (rest_positions_mm[s.b] - rest_positions_mm[s.a]).normalized();
    const Eigen::Matrix3d block = s.stiffness_mn_per_mm * dir * dir.transpose();
    node_rows[s.a].add(block, pinned[s.b]);
    node_rows[s.b].add(block, pinned[s.a]);
  }
  std::vector<double> rows(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!pinned[i]) rows[i] = node_rows[i].value();
  }
  return rows;
}

}  // namespace

double msds_max_omega_squared_bound(std::span<const Eigen::Vector3d> rest_positions_mm,
                                    std::span<const MsdsSpring> springs,
                                    std::span<const double> node_masses_kg,
                                    std::span<const std::uint8_t> pinned) {
  const std::vector<double> rows = gershgorin_row_sums(rest_positions_mm, springs, pinned);
  // mN/mm / kg = (kg·mm/s²)/mm / kg = 1/s².
  double bound = 0.0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (pinned[i] || !(node_masses_kg[i] > 0.0)) continue;
    bound = std::max(bound, rows[i] / node_masses_kg[i]);
  }
  return bound;
}

double msds_max_stable_omega_squared(double time_step_s, double damping_per_stiffness_s) {
  // forward_euler_stable_time_step_s is non-increasing in ω²: bisect on a log scale.
  if (!(forward_euler_stable_time_step_s(1e-12, damping_per_stiffness_s) >= time_step_s)) {
    return 0.0;  // no mass makes it stable (dt above β, or no damping)
  }
  double lo = 1e-12, hi = 1e30;
  for (int i = 0; i < 200; ++i) {
    const double mid = std::sqrt(lo * hi);
    if (forward_euler_stable_time_step_s(mid, damping_per_stiffness_s) >= time_step_s) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

double forward_euler_stable_time_step_s(double omega_squared, double damping_per_stiffness_s) {
  const double beta = damping_per_stiffness_s;
  const double omega = std::sqrt(omega_squared);
  if (beta * omega <= 2.0) return beta;
  return 4.0 / (beta * omega_squared + omega * std::sqrt(beta * beta * omega_squared - 4.0));
}

MsdsEngine::MsdsEngine(MsdsIntegrator integrator, const geometry::TetMesh& mesh,
                       std::span<const Material> tet_materials,
                       std::span<const std::uint8_t> fixed_nodes, const MsdsSettings& settings,
                       hal::JobSystem* jobs, std::span<const std::uint8_t> reachable_nodes)
    : integrator_(integrator),
      settings_(settings),
      jobs_(jobs),
      // The implicit step on one thread: its stages are short (a 32×16×16 grid's CG iteration
      // ~20 µs, vectorised), and handing each to a second thread cost more than it saved (frames
      // of 24×12×12 and 32×16×16 grids 9.5 and 23.5 ms on one thread, 15.9 and 29.9 on two;
      // engine_bench). The other core stays free for the frame's other tasks.
      team_(std::make_unique<msds_detail::TaskTeam>(
          integrator == MsdsIntegrator::kExplicitEuler ? jobs : nullptr)) {
  check_settings(settings);
  check_tet_model("MsdsEngine", mesh, tet_materials, fixed_nodes);
  rest_ = mesh.rest_positions_mm;
  tets_ = mesh.tets;
  require(reachable_nodes.empty() || reachable_nodes.size() == rest_.size(),
          "need no reachable-node flags or one per node");
  on_surface_ = reachable_nodes.empty()
                    ? geometry::boundary_node_flags(mesh)
                    : std::vector<std::uint8_t>(reachable_nodes.begin(), reachable_nodes.end());
  build_springs(mesh, tet_materials);
  build_masses(mesh);
  // A node in no tet has no mass and no spring: nothing could move it, so it never moves.
  pinned_.assign(rest_.size() + kNodePadding, 1);
  for (std::size_t i = 0; i < rest_.size(); ++i) {
    pinned_[i] = fixed_nodes[i] != 0 || !(mass_kg_[i] > 0.0);
  }
  if (integrator_ == MsdsIntegrator::kExplicitEuler && settings_.scale_mass_for_explicit_step) {
    scale_masses_to_time_step();
  }
  build_speed_ceilings();
  build_adjacency();
  size_buffers();
  build_contact_clusters();
  if (integrator_ == MsdsIntegrator::kExplicitEuler) build_explicit_kernel();
}

MsdsEngine::~MsdsEngine() = default;

void MsdsEngine::NodeVectors::assign_zero(int node_count) {
  for (auto* a : {&x, &y, &z}) a->assign(static_cast<std::size_t>(node_count + kNodePadding), 0.0);
}

void MsdsEngine::NodeVectors::set(int node, const Eigen::Vector3d& value) {
  x[node] = value.x();
  y[node] = value.y();
  z[node] = value.z();
}

void MsdsEngine::NodeVectors::copy_from(const NodeVectors& other) {
  std::copy(other.x.begin(), other.x.end(), x.begin());
  std::copy(other.y.begin(), other.y.end(), y.begin());
  std::copy(other.z.begin(), other.z.end(), z.begin());
}

void MsdsEngine::build_springs(const geometry::TetMesh& mesh,
                               std::span<const Material> tet_materials) {
  // Every tet's six edges, sorted so that an edge's tets are adjacent (in tet order, which fixes
  // the order the merged stiffness is summed in).
  std::vector<std::tuple<std::int32_t, std::int32_t, int>> edges;
  edges.reserve(mesh.tets.size() * 6);
  for (int t = 0; t < mesh.tet_count(); ++t) {
    const auto& tet = mesh.tets[t];
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        edges.emplace_back(std::min(tet[i], tet[j]), std::max(tet[i], tet[j]), t);
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const auto [a, b, t] = edges[e];
    const double k = tet_materials[t].youngs_modulus_kpa * settings_.stiffness_per_modulus_mm;
    if (e > 0 && std::get<0>(edges[e - 1]) == a && std::get<1>(edges[e - 1]) == b) {
      springs_.back().stiffness_mn_per_mm += k;
      continue;
    }
    springs_.push_back({a, b, (rest_[b] - rest_[a]).norm(), k, 0.0});
  }
  // Damped springs only turn elastic energy into motion, and no sane press strains every spring by
  // its own length: kinetic energy beyond that is an integrator blowing up.
  kinetic_energy_ceiling_uj_ = 0.0;
  for (auto& s : springs_) {
    s.damping_mn_s_per_mm = s.stiffness_mn_per_mm * settings_.damping_per_stiffness_s;
    kinetic_energy_ceiling_uj_ += 0.5 * s.stiffness_mn_per_mm * s.rest_length_mm * s.rest_length_mm;
  }
}

void MsdsEngine::build_masses(const geometry::TetMesh& mesh) {
  mass_kg_.assign(rest_.size(), 0.0);
  const double kg_per_mm3 = settings_.density_kg_per_m3 * kKgPerMm3PerKgPerM3;
  for (const auto& tet : mesh.tets) {
    const double volume_mm3 =
        geometry::signed_tet_volume(rest_[tet[0]], rest_[tet[1]], rest_[tet[2]], rest_[tet[3]]);
    for (auto node : tet) mass_kg_[node] += 0.25 * volume_mm3 * kg_per_mm3;
  }
}

void MsdsEngine::scale_masses_to_time_step() {
  // 20 % margin below the limit: the Gershgorin bound is within ~1.5× of the true limit, and a
  // compressed spring's transverse stiffness can add a little.
  const double omega_squared_max =
      msds_max_stable_omega_squared(1.2 * settings_.time_step_s, settings_.damping_per_stiffness_s);
  if (!(omega_squared_max > 0.0)) {
    throw std::invalid_argument(
        "MsdsSettings: time_step_s must be below damping_per_stiffness_s for explicit Euler to be "
        "stable at any mass");
  }
  gershgorin_row_mn_per_mm_ =
      gershgorin_row_sums(rest_, springs_, std::span(pinned_).first(rest_.size()));
  stable_omega_squared_ = omega_squared_max;
  physical_mass_kg_ = mass_kg_;
  double physical = 0.0, scaled = 0.0;
  for (std::size_t i = 0; i < mass_kg_.size(); ++i) {
    if (pinned_[i]) continue;
    physical += mass_kg_[i];
    mass_kg_[i] = std::max(mass_kg_[i], gershgorin_row_mn_per_mm_[i] / omega_squared_max);
    scaled += mass_kg_[i];
  }
  mass_scale_ = physical > 0.0 ? scaled / physical : 1.0;
}

void MsdsEngine::build_speed_ceilings() {
  // The global kinetic energy ceiling misses one node running away: a lattice of 20,000 springs
  // holds far more energy than one node's six. A spring's sideways stiffness is k(1 − L/l) at
  // length l (up to k pulled long, negative squeezed), which the rest-state stability bound
  // leaves out: under a deep press one node can pass the explicit step's bound on its own. On the
  // large case one reached 600 mm and 150 m/s within a few frames, its springs' damping reading
  // 4 kN at the probe: one node inverts fewer tets than the 0.5 % a frame may keep. Checked node
  // by node, the same ceiling: no node moves faster than its own springs' energy at 100 % strain
  // could move it, ½ m v² ≤ ½ Σ k L². An overdamped lattice relaxing from that strain moves a
  // node at about L/β: with the masses scaled to the step, m ≈ Σ k / ω², its kinetic energy is
  // then ~dt / (2β) ≈ 3 % of the ceiling, its speed 1 / (βω) ≈ 17 % of the ceiling's.
  speed_ceiling_squared_.assign(rest_.size(), std::numeric_limits<double>::infinity());
  std::vector<double> capacity_uj(rest_.size(), 0.0);
  for (const auto& s : springs_) {
    const double twice_energy_uj = s.stiffness_mn_per_mm * s.rest_length_mm * s.rest_length_mm;
    capacity_uj[s.a] += twice_energy_uj;
    capacity_uj[s.b] += twice_energy_uj;
  }
  for (std::size_t i = 0; i < rest_.size(); ++i) {
    // µJ / kg = mm²/s². Masses an anchor raises later keep this (looser) ceiling.
    if (!pinned_[i]) speed_ceiling_squared_[i] = capacity_uj[i] / mass_kg_[i];
  }
}

void MsdsEngine::set_anchor_springs(std::span<const AnchorSpring> anchors) {
  check_anchor_springs(anchors, node_count());
  for (const auto& a : anchors_) {
    anchor_stiffness_mn_per_mm_[a.node] = 0.0;
    anchor_of_node_[a.node] = -1;
  }
  anchors_.assign(anchors.begin(), anchors.end());
  for (std::size_t i = 0; i < anchors_.size(); ++i) {
    anchor_stiffness_mn_per_mm_[anchors_[i].node] = anchors_[i].stiffness_mn_per_mm;
    anchor_of_node_[anchors_[i].node] = static_cast<int>(i);
  }
  if (physical_mass_kg_.empty()) return;
  // A node's stable step depends on its total stiffness: an anchor (with its damping, like a
  // spring's) adds k to its Gershgorin row. Only nodes whose anchor changed are rescaled.
  bool changed = false;
  for (int i = 0; i < node_count(); ++i) {
    if (pinned_[i] || mass_scaled_for_anchor_mn_per_mm_[i] == anchor_stiffness_mn_per_mm_[i]) {
      continue;
    }
    rescale_anchored_mass(i, anchor_stiffness_mn_per_mm_[i]);
    changed = true;
  }
  if (!changed) return;
  recount_mass_scale();
}

void MsdsEngine::recount_mass_scale() {
  double physical = 0.0, scaled = 0.0;
  for (int i = 0; i < node_count(); ++i) {
    if (pinned_[i]) continue;
    physical += physical_mass_kg_[i];
    scaled += mass_kg_[i];
  }
  mass_scale_ = physical > 0.0 ? scaled / physical : 1.0;
}

void MsdsEngine::rescale_anchored_mass(int node, double anchor_stiffness_mn_per_mm) {
  mass_kg_[node] = std::max(
      physical_mass_kg_[node],
      (gershgorin_row_mn_per_mm_[node] + anchor_stiffness_mn_per_mm) / stable_omega_squared_);
  padded_mass_kg_[node] = mass_kg_[node];
  inverse_mass_per_kg_[node] = 1.0 / mass_kg_[node];
  mass_scaled_for_anchor_mn_per_mm_[node] = anchor_stiffness_mn_per_mm;
}

void MsdsEngine::weigh_runaway_nodes() {
  // A node runs away when its springs, pulled long, stiffen it sideways past the rest stiffness
  // its mass was scaled for. Kept at the frame's start it is still pulled long there, and would
  // run away again in every frame short of time for smaller steps (345 frames refused in a row
  // in the large soak). So, as explicit FE codes scale the mass of the elements that limit the
  // step, its mass is scaled again for its springs' stiffness where the frame starts (the
  // statics do not change; that node follows more slowly). Without mass scaling there is no
  // mass to spare: smaller steps only.
  if (!(stable_omega_squared_ > 0.0)) return;
  bool weighed = false;
  for (int i = 0; i < node_count(); ++i) {
    if (pinned_[i] || !outruns_its_springs(i)) continue;
    const double row = stretched_gershgorin_row_mn_per_mm(i);
    if (!(row > gershgorin_row_mn_per_mm_[i])) continue;
    gershgorin_row_mn_per_mm_[i] = row;
    rescale_anchored_mass(i, anchor_stiffness_mn_per_mm_[i]);
    weighed = true;
  }
  if (!weighed) return;
  recount_mass_scale();
}

double MsdsEngine::stretched_gershgorin_row_mn_per_mm(int node) const {
  // As gershgorin_row_sums, with each spring's stiffness at its length l at the frame's start:
  // k [n nᵀ + g (I − n nᵀ)], g = 1 − L/l (kept within ±1: a spring squeezed below half its
  // length buckles, which no mass steadies).
  GershgorinRow row;
  const Eigen::Vector3d x = position_frame_start_[node];
  for (int e = adjacency_begin_[node]; e < adjacency_begin_[node + 1]; ++e) {
    const MsdsSpring& spring = springs_[adjacency_spring_[e]];
    const int other = adjacency_other_[e];
    const Eigen::Vector3d d = position_frame_start_[other] - x;
    const double length = d.norm();
    if (!(length > 0.0)) continue;
    const Eigen::Vector3d n = d / length;
    const double g = std::clamp(1.0 - spring.rest_length_mm / length, -1.0, 1.0);
    const Eigen::Matrix3d block =
        spring.stiffness_mn_per_mm *
        (n * n.transpose() + g * (Eigen::Matrix3d::Identity() - n * n.transpose()));
    row.add(block, pinned_[other] != 0);
  }
  return row.value();
}

void MsdsEngine::build_adjacency() {
  const int n = node_count();
  adjacency_begin_.assign(n + 1, 0);
  for (const auto& s : springs_) {
    ++adjacency_begin_[s.a + 1];
    ++adjacency_begin_[s.b + 1];
  }
  for (int i = 0; i < n; ++i) adjacency_begin_[i + 1] += adjacency_begin_[i];
  adjacency_spring_.resize(adjacency_begin_[n]);
  adjacency_other_.resize(adjacency_begin_[n]);
  std::vector<int> fill(adjacency_begin_.begin(), adjacency_begin_.end() - 1);
  for (int s = 0; s < static_cast<int>(springs_.size()); ++s) {
    const auto& spring = springs_[s];
    adjacency_spring_[fill[spring.a]] = s;
    adjacency_other_[fill[spring.a]++] = spring.b;
    adjacency_spring_[fill[spring.b]] = s;
    adjacency_other_[fill[spring.b]++] = spring.a;
  }
}

void MsdsEngine::size_buffers() {
  const int n = node_count();
  const auto padded = static_cast<std::size_t>(n + kNodePadding);
  position_.assign_zero(n);
  velocity_.assign_zero(n);
  for (int i = 0; i < n; ++i) position_.set(i, rest_[i]);
  position_frame_start_.assign_zero(n);
  velocity_frame_start_.assign_zero(n);
  x_ = rest_;
  v_.assign(rest_.size(), Eigen::Vector3d::Zero());
  u_ = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(n));
  padded_mass_kg_.assign(padded, 0.0);
  inverse_mass_per_kg_.assign(padded, 0.0);
  for (int i = 0; i < n; ++i) {
    padded_mass_kg_[i] = mass_kg_[i];
    if (!pinned_[i]) inverse_mass_per_kg_[i] = 1.0 / mass_kg_[i];
  }
  // find_contacts never needs more than every node: step() does not allocate.
  contacts_.reserve(rest_.size());
  candidate_nodes_.reserve(rest_.size());
  candidate_positions_mm_.reserve(rest_.size());
  candidate_fixed_.assign(rest_.size(), 0);
  // Pinned nodes are never queried: an infinite clearance keeps them out of every block's minimum.
  probe_clearance_mm_.assign(padded, std::numeric_limits<double>::infinity());
  for (int i = 0; i < n; ++i) {
    if (!pinned_[i]) probe_clearance_mm_[i] = 0.0;
  }
  block_min_clearance_mm_.assign(static_cast<std::size_t>(node_chunk_count()), 0.0);
  held_.assign(padded, 0);
  touching_only_.assign(rest_.size(), 0);
  contact_normal_.assign(rest_.size(), Eigen::Vector3d::UnitZ());
  anchor_stiffness_mn_per_mm_.assign(rest_.size(), 0.0);
  anchor_of_node_.assign(rest_.size(), -1);
  mass_scaled_for_anchor_mn_per_mm_.assign(rest_.size(), 0.0);
  if (integrator_ == MsdsIntegrator::kImplicitEuler) {
    implicit_lattice_ = std::make_unique<msds_detail::ImplicitLattice>(rest_, springs_);
    for (auto* buffer : {&node_elastic_, &node_block_diagonal_, &inverse_diagonal_, &rhs_, &r_, &z_,
                         &p_, &q_, &cg_velocity_}) {
      buffer->assign_zero(n);
    }
    system_diagonal_.assign(padded, 0.0);
  }
  tet_lattice_ = std::make_unique<msds_detail::TetLattice>(tets_, n);
  const int chunks = std::max({node_chunk_count(), tet_lattice_->chunk_count(), 1});
  partial_a_.assign(chunks, 0.0);
  partial_b_.assign(chunks, 0.0);
  partial_c_.assign(chunks, 0.0);
  partial_d_.assign(chunks, 0.0);
  partial_e_.assign(chunks, 0.0);
  partial_finite_.assign(chunks, 1);
  partial_runaway_.assign(chunks, 0);
}

void MsdsEngine::build_contact_clusters() {
  // Cubic cells about two mesh spacings wide (~8 nodes of a grid): one query per cell, and few
  // nodes queried one by one near the probe.
  Eigen::AlignedBox3d box;
  for (const auto& p : rest_) box.extend(p);
  const double volume = std::max(box.volume(), 1e-9);
  const double cell_mm = 2.0 * std::cbrt(volume / static_cast<double>(rest_.size()));
  std::map<std::array<long, 3>, std::vector<int>> cells;
  for (int i = 0; i < node_count(); ++i) {
    if (pinned_[i]) continue;
    const Eigen::Vector3d cell = ((rest_[i] - box.min()) / cell_mm).array().floor();
    cells[{static_cast<long>(cell.x()), static_cast<long>(cell.y()), static_cast<long>(cell.z())}]
        .push_back(i);
  }
  cluster_begin_.assign(1, 0);
  for (const auto& [cell, nodes] : cells) {
    Eigen::AlignedBox3d cell_box;
    for (int i : nodes) cell_box.extend(rest_[i]);
    cluster_center_mm_.push_back(cell_box.center());
    cluster_nodes_.insert(cluster_nodes_.end(), nodes.begin(), nodes.end());
    cluster_begin_.push_back(static_cast<int>(cluster_nodes_.size()));
  }
}

// The explicit step's float kernel, split over tasks: task t sweeps the node blocks
// [first_block[t], first_block[t + 1]) with its own scratch.
struct MsdsEngine::ExplicitKernel {
  explicit ExplicitKernel(msds_detail::SpringLattice springs) : lattice(std::move(springs)) {}

  int task_count() const { return static_cast<int>(sweeps.size()); }

  msds_detail::SpringLattice lattice;
  std::vector<int> first_block;
  std::vector<msds_detail::SpringLattice::Sweep> sweeps;
  // Per task: the force on one block's nodes, x then y then z, each kBlockForceStride long.
  static constexpr int kBlockForceStride = kNodesPerChunk + kNodePadding;
  std::vector<std::vector<float>> block_force;
  // The state at the start of the step (state[current]) and the one the step writes.
  msds_detail::FloatNodeState state[2];
  int current = 0;
};

void MsdsEngine::build_explicit_kernel() {
  const int blocks = node_chunk_count();
  // One task per thread: each task's first block recomputes the slots below it (a halo of the
  // largest diagonal offset), so fewer, longer runs cost less.
  const int tasks = std::clamp(team_->thread_count(), 1, blocks);
  explicit_ = std::make_unique<ExplicitKernel>(
      msds_detail::SpringLattice(rest_, springs_, settings_.damping_per_stiffness_s));
  ExplicitKernel& k = *explicit_;
  for (int t = 0; t <= tasks; ++t) k.first_block.push_back(t * blocks / tasks);
  for (int t = 0; t < tasks; ++t) {
    const int begin = k.first_block[t] * kNodesPerChunk;
    const int end = std::min(node_count(), k.first_block[t + 1] * kNodesPerChunk);
    k.sweeps.push_back(k.lattice.make_sweep(begin, end));
    k.block_force.emplace_back(3 * ExplicitKernel::kBlockForceStride, 0.0f);
  }
  for (auto& state : k.state) state.assign_zero(node_count());
  sync_float_state();
}

EngineKind MsdsEngine::kind() const {
  return integrator_ == MsdsIntegrator::kExplicitEuler ? EngineKind::kMsdsExplicit
                                                       : EngineKind::kMsdsImplicit;
}

std::string_view MsdsEngine::name() const {
  return integrator_ == MsdsIntegrator::kExplicitEuler ? "MSDS explicit Euler"
                                                       : "MSDS implicit Euler";
}

double MsdsEngine::sum_partials(const std::vector<double>& partials, int chunks) const {
  double sum = 0.0;
  for (int chunk = 0; chunk < chunks; ++chunk) sum += partials[chunk];
  return sum;
}

MsdsEngine::StepResult MsdsEngine::gather_update_result() const {
  StepResult result;
  const int chunks = node_chunk_count();
  result.kinetic_energy_uj = sum_partials(partial_a_, chunks);
  for (int chunk = 0; chunk < chunks; ++chunk)
    result.finite = result.finite && partial_finite_[chunk];
  return result;
}

int MsdsEngine::node_chunk_count() const {
  return chunk_count(node_count(), kNodesPerChunk);
}

// ---------------------------------------------------------------------------------------------
// Frame, recovery.

EngineStepStats MsdsEngine::step(const ProbeCollider* probe, double /*frame_dt_s*/) {
  EngineStepStats stats;
  team_->run([&] { stats = run_frame(probe); });
  return stats;
}

EngineStepStats MsdsEngine::step_within(const ProbeCollider* probe, double frame_dt_s,
                                        const StepBudget& may_continue) {
  if (!may_continue) return step(probe, frame_dt_s);
  budget_ = &may_continue;
  cut_short_ = false;
  // The budget is the caller's: never keep it past this call, even if the step throws.
  struct Forget {
    const StepBudget*& budget;
    ~Forget() { budget = nullptr; }
  } forget{budget_};
  EngineStepStats stats = step(probe, frame_dt_s);
  stats.cut_short = cut_short_;
  return stats;
}

void MsdsEngine::stretch_next_frame(int frames) {
  require(frames >= 1 && frames <= kMaxFrameStretch,
          "stretch_next_frame: frames must be in [1, " + std::to_string(kMaxFrameStretch) + "]");
  next_frame_stretch_ = frames;
}

EngineStepStats MsdsEngine::run_frame(const ProbeCollider* probe) {
  const int stretch = std::exchange(next_frame_stretch_, 1);
  position_frame_start_.copy_from(position_);
  velocity_frame_start_.copy_from(velocity_);
  inverted_at_frame_start_ = -1;  // counted if a try goes over the limit
  // The frame's simulated time, steps × dt, in the explicit engine's steps or in fewer, larger
  // implicit ones.
  const bool implicit = integrator_ == MsdsIntegrator::kImplicitEuler;
  const int steps =
      implicit ? settings_.implicit_steps_per_frame : settings_.steps_per_frame * stretch;
  const double dt = settings_.time_step_s * settings_.steps_per_frame * stretch / steps;
  EngineStepStats stats;
  AttemptResult attempt = run_attempt(probe, dt, steps);
  if (!attempt.accepted) {
    stats.diverged = true;
    stats.cause = attempt.cause;  // why the frame was re-run, whatever the later tries found
    stats.inverted_tets = attempt.inverted_tets;
    if (attempt.cause == DivergenceCause::kRunaway) weigh_runaway_nodes();
    // Under a budget, smaller steps are tried only while there is time (each try doubles the
    // steps): past it, the frame keeps its start, as for a refused press.
    bool out_of_time = false;
    for (int halvings = 1; halvings <= kMaxHalvings && !attempt.accepted; ++halvings) {
      if (budget_ != nullptr && !(*budget_)()) {
        out_of_time = cut_short_ = true;
        break;
      }
      position_.copy_from(position_frame_start_);
      velocity_.copy_from(velocity_frame_start_);
      truncated_velocity_kept_ = false;
      sync_float_state();
      attempt = run_attempt(probe, dt / (1 << halvings), steps << halvings);
    }
    if (attempt.accepted) {
      stats.recovery = Recovery::kSubstepped;
    } else if (!attempt.blew_up || out_of_time) {
      // Smaller steps cannot help a probe that folds tets under its rim (the spring lattice has
      // no volume stiffness to stop it): show the frame's start, at rest, rather than flicker
      // to the undeformed tissue.
      position_.copy_from(position_frame_start_);
      velocity_.assign_zero(node_count());
      truncated_velocity_kept_ = false;
      sync_float_state();
      stats.recovery = Recovery::kKeptLastGood;
    } else {
      reset_to_rest();
      stats.recovery = Recovery::kReset;
    }
  }
  // A frame that stands reports its own folds; one kept or reset, its first attempt's.
  if (attempt.accepted) stats.inverted_tets = attempt.inverted_tets;
  stats.iterations = attempt.iterations;
  stats.relative_residual = attempt.relative_residual;
  stats.contact_nodes = held_node_count();
  stats.contact_force_n = contact_force_n();
  publish_state();
  return stats;
}

MsdsEngine::AttemptResult MsdsEngine::run_attempt(const ProbeCollider* probe, double dt_s,
                                                  int steps) {
  AttemptResult out;
  // Counting inverted tets costs about half an explicit step (msds_tet_lattice.hpp) and a few
  // percent of an implicit one: every implicit step, every 4th explicit one (an explicit
  // instability shows in the kinetic energy first), and always after the last, so a failing attempt
  // stops early and a frame the probe inverts costs a few steps per try, not the whole frame. Not
  // after the first step (unless it is the last): the probe's whole move since the last frame lands
  // there at once and may fold the tets under it for that one step; the springs unfold them in the
  // next.
  const int check_every = integrator_ == MsdsIntegrator::kExplicitEuler ? 4 : 1;
  for (int s = 0; s < steps; ++s) {
    // The probe may have moved since the last frame (or try): the first step queries every node.
    const StepResult r = advance(probe, dt_s, s == 0);
    out.iterations += integrator_ == MsdsIntegrator::kExplicitEuler ? 1 : r.cg_iterations;
    out.relative_residual = std::max(out.relative_residual, r.cg_relative_residual);
    // `!(a <= b)` also catches a NaN energy.
    if (!r.finite || !(r.kinetic_energy_uj <= kinetic_energy_ceiling_uj_)) {
      out.blew_up = true;
      out.cause = r.finite && std::isfinite(r.kinetic_energy_uj) ? DivergenceCause::kEnergy
                                                                 : DivergenceCause::kNonFinite;
      return out;
    }
    // Under a budget the explicit integrator stops stepping when the time is spent: the frame
    // integrates less simulated time and the tissue lags the probe, as a CG cut short does,
    // instead of the frame running late. Its steps are fixed work (20 a frame, ~1.5 ms for a 15³
    // sub-volume on the kiosk's cores), and the large case's touched sub-volumes took 6-8 ms of
    // the simulation's 4 ms share with every step run. It asks from the first inverted-tet check
    // on (check_every steps), never after the first step alone, whose folds the next undoes. The
    // implicit integrator's steps keep the frame's time (its CG is what the budget cuts).
    const bool out_of_time = integrator_ == MsdsIntegrator::kExplicitEuler && budget_ != nullptr &&
                             s + 1 >= check_every && s + 1 < steps && !(*budget_)();
    if (out_of_time) cut_short_ = true;
    const bool last = s + 1 == steps || out_of_time;
    if (!last && (s == 0 || (s + 1) % check_every != 0)) continue;
    out.inverted_tets = count_inverted_tets(position_);
    // A few tets folded under the probe's rim are the lattice's weakness, not a blow-up; many
    // are garbage (as for the FEM engines: max_inverted_fraction of all tets, or the folds the
    // frame started with, which it may keep while it unfolds them). Only while the probe holds
    // tissue: untouched, the lattice's folds are its own as it relaxes, and keeping the start
    // (as folded) would only stop it relaxing (the default case's implicit MSDS refused its
    // relaxation for 450 frames with ~200 tets folded, its limit). A node running away is
    // garbage too (build_speed_ceilings): like a fold, smaller steps are tried while there is
    // time, then the frame keeps its start, at rest (and the node is weighed: run_frame).
    if (static_cast<double>(out.inverted_tets) >
            settings_.max_inverted_fraction * static_cast<double>(tets_.size()) &&
        held_node_count() > 0 && out.inverted_tets > inverted_at_frame_start()) {
      out.cause = DivergenceCause::kInverted;
      return out;
    }
    if (a_node_outruns_its_springs()) {  // a runaway the tets' count has not seen (yet)
      out.cause = DivergenceCause::kRunaway;
      return out;
    }
    if (out_of_time) break;
  }
  out.accepted = true;
  return out;
}

int MsdsEngine::inverted_at_frame_start() {
  if (inverted_at_frame_start_ < 0)
    inverted_at_frame_start_ = count_inverted_tets(position_frame_start_);
  return inverted_at_frame_start_;
}

int MsdsEngine::count_inverted_tets(const NodeVectors& at) {
  const int chunks = tet_lattice_->chunk_count();
  const double* x = at.x.data();
  const double* y = at.y.data();
  const double* z = at.z.data();
  for_each_chunk(chunks,
                 [&](int chunk) { partial_a_[chunk] = tet_lattice_->count(chunk, x, y, z); });
  return static_cast<int>(sum_partials(partial_a_, chunks));
}

bool MsdsEngine::outruns_its_springs(int node) const {
  // `!(a <= b)` also catches a NaN speed.
  return !(velocity_[node].squaredNorm() <= speed_ceiling_squared_[node]);
}

bool MsdsEngine::a_node_outruns_its_springs() {
  const int n = node_count();
  const int chunks = node_chunk_count();
  for_each_chunk(chunks, [&](int chunk) {
    bool runs = false;
    const int end = std::min(n, (chunk + 1) * kNodesPerChunk);
    for (int i = chunk * kNodesPerChunk; i < end; ++i) runs = runs || outruns_its_springs(i);
    partial_runaway_[chunk] = runs;
  });
  return std::any_of(partial_runaway_.begin(), partial_runaway_.begin() + chunks,
                     [](std::uint8_t runs) { return runs != 0; });
}

void MsdsEngine::integrate_unchecked(const ProbeCollider* probe, double dt_s, int steps) {
  team_->run([&] {
    for (int s = 0; s < steps; ++s) advance(probe, dt_s, s == 0);
  });
  publish_state();
}

MsdsEngine::StepResult MsdsEngine::advance(const ProbeCollider* probe, double dt_s,
                                           bool new_probe) {
  apply_contacts(probe, new_probe);
  if (integrator_ == MsdsIntegrator::kExplicitEuler) return explicit_euler_update(dt_s);
  return implicit_euler_update(dt_s);
}

void MsdsEngine::reset_to_rest() {
  truncated_velocity_kept_ = false;
  for (int i = 0; i < node_count(); ++i) position_.set(i, rest_[i]);
  velocity_.assign_zero(node_count());
  clear_contacts();
  sync_float_state();
}

void MsdsEngine::sync_float_state() {
  if (!explicit_) return;
  msds_detail::FloatNodeState& state = explicit_->state[explicit_->current];
  for (int i = 0; i < node_count(); ++i) state.set(i, position_[i], velocity_[i]);
}

void MsdsEngine::publish_state() {
  for (int i = 0; i < node_count(); ++i) {
    x_[i] = position_[i];
    v_[i] = velocity_[i];
    u_.segment<3>(3 * i) = x_[i] - rest_[i];
  }
}

void MsdsEngine::set_displacements_mm(const Eigen::VectorXd& u_mm) {
  if (u_mm.size() != 3 * static_cast<Eigen::Index>(node_count())) {
    throw std::invalid_argument(
        "MSDS: set_displacements_mm needs 3 × node count = " + std::to_string(3 * node_count()) +
        " entries, got " + std::to_string(u_mm.size()));
  }
  if (!u_mm.allFinite()) {
    throw std::invalid_argument("MSDS: set_displacements_mm got a non-finite displacement");
  }
  for (int i = 0; i < node_count(); ++i) {
    const Eigen::Vector3d u =
        pinned_[i] ? Eigen::Vector3d::Zero() : Eigen::Vector3d(u_mm.segment<3>(3 * i));
    position_.set(i, rest_[i] + u);
  }
  velocity_.assign_zero(node_count());
  truncated_velocity_kept_ = false;
  clear_contacts();
  sync_float_state();
  publish_state();
  // u_ keeps the given field exactly (not rest + u − rest), so switching back and forth between
  // engines does not drift by rounding.
  for (int i = 0; i < node_count(); ++i) {
    if (!pinned_[i]) u_.segment<3>(3 * i) = u_mm.segment<3>(3 * i);
  }
}

// ---------------------------------------------------------------------------------------------
// Contact and forces.

void MsdsEngine::clear_contacts() {
  for (const auto& c : contacts_) held_[c.node] = touching_only_[c.node] = 0;
  contacts_.clear();
}

void MsdsEngine::apply_contacts(const ProbeCollider* probe, bool new_probe) {
  clear_contacts();
  if (probe == nullptr) return;
  collect_contact_candidates(*probe, new_probe);
  // The published collision test, on the nodes that may pass it.
  find_contacts(*probe, candidate_positions_mm_,
                std::span(candidate_fixed_).first(candidate_positions_mm_.size()),
                kTouchToleranceMm, contacts_);
  // As published: onto the probe's surface. The probe does not move within a frame, so a node
  // held on it has zero velocity (zeroed, not just its normal part: the contact is sticky while
  // held, as the published FEM's Dirichlet contact).
  for (auto& c : contacts_) {
    c.node = candidate_nodes_[c.node];
    position_.set(c.node, c.target_mm);
    velocity_.set(c.node, Eigen::Vector3d::Zero());
    held_[c.node] = 1;
    touching_only_[c.node] = c.depth_mm <= kTouchToleranceMm;
    contact_normal_[c.node] = c.normal;
  }
  // Once every caught node is on the surface, so each slides against its neighbours' new places.
  // Only a node on the tissue's surface slides: one inside it, caught while the springs lag
  // behind a deep press, slid past the surface node over it and folded the tets between, which
  // the springs (no volume stiffness) never unfold (a 4 mm press slid along a slab of 2 mm tets:
  // 128 at once); held where caught, it is let go as the springs push it off the probe.
  if (settings_.contact.model == HeldContactModel::kCoulombSlip) {
    for (auto& c : contacts_) {
      if (on_surface_[c.node]) slide_along_probe(*probe, c);
    }
  }
  if (explicit_) {
    for (const auto& c : contacts_) {
      explicit_->state[explicit_->current].set(c.node, c.target_mm, Eigen::Vector3d::Zero());
    }
  }
}

void MsdsEngine::slide_along_probe(const ProbeCollider& probe, NodeContact& c) {
  Eigen::Vector3d elastic;
  Eigen::Matrix3d stiffness;
  elastic_force_and_stiffness(c.node, elastic, stiffness);
  const SurfacePoint slid = slide_held_node(probe, {c.target_mm, c.normal}, elastic, stiffness,
                                            settings_.contact.friction_coefficient);
  c.target_mm = slid.point_mm;
  c.normal = slid.normal;
  position_.set(c.node, c.target_mm);
  contact_normal_[c.node] = c.normal;
}

void MsdsEngine::elastic_force_and_stiffness(int node, Eigen::Vector3d& elastic_mn,
                                             Eigen::Matrix3d& stiffness_mn_per_mm) const {
  // The springs' material stiffness along their present directions (their tension's sideways
  // stiffness left out: it is small for springs near their rest length, and leaving it out
  // only shortens a slide); the anchor's on the diagonal.
  elastic_mn.setZero();
  stiffness_mn_per_mm = Eigen::Matrix3d::Identity() * anchor_stiffness_mn_per_mm_[node];
  for (int e = adjacency_begin_[node]; e < adjacency_begin_[node + 1]; ++e) {
    const MsdsSpring& s = springs_[adjacency_spring_[e]];
    double length = 0.0;
    const Eigen::Vector3d dir =
        spring_direction(node, adjacency_other_[e], s.rest_length_mm, length);
    elastic_mn += s.stiffness_mn_per_mm * (length - s.rest_length_mm) * dir;
    stiffness_mn_per_mm.noalias() += s.stiffness_mn_per_mm * dir * dir.transpose();
  }
  Eigen::Vector3d anchor_elastic, anchor_damping;
  anchor_force(node, anchor_elastic, anchor_damping);
  elastic_mn += anchor_elastic;
}

// The probe's signed distance is a distance (1-Lipschitz): it changes no faster than a node
// moves, and over a ball of radius r it is within r of its value at the centre. A node whose bound
// on it (probe_clearance_mm_) is above the contact tolerance cannot be in contact and is not
// queried. `!(a >= b)` below also queries a NaN.

void MsdsEngine::collect_contact_candidates(const ProbeCollider& probe, bool new_probe) {
  candidate_nodes_.clear();
  if (new_probe) {
    query_every_cluster(probe);
  } else {
    query_nodes_near_probe(probe);
  }
  std::sort(candidate_nodes_.begin(), candidate_nodes_.end());
  candidate_positions_mm_.clear();
  for (int node : candidate_nodes_) candidate_positions_mm_.push_back(position_[node]);
}

void MsdsEngine::query_every_cluster(const ProbeCollider& probe) {
  for (std::size_t c = 0; c + 1 < cluster_begin_.size(); ++c) {
    const Eigen::Vector3d& center = cluster_center_mm_[c];
    double radius_squared = 0.0;
    for (int e = cluster_begin_[c]; e < cluster_begin_[c + 1]; ++e) {
      const double d2 = (position_[cluster_nodes_[e]] - center).squaredNorm();
      if (!(d2 <= radius_squared)) radius_squared = d2;  // NaN sticks
    }
    const double bound = probe.signed_distance_mm(center) - std::sqrt(radius_squared);
    for (int e = cluster_begin_[c]; e < cluster_begin_[c + 1]; ++e) {
      if (bound >= kCandidateReachMm) {
        probe_clearance_mm_[cluster_nodes_[e]] = bound;
      } else {
        query_node(probe, cluster_nodes_[e]);
      }
    }
  }
  update_block_min_clearances();
}

void MsdsEngine::query_nodes_near_probe(const ProbeCollider& probe) {
  // Only blocks whose least bound reaches the probe hold nodes to query.
  for (int block = 0; block < node_chunk_count(); ++block) {
    double& block_min = block_min_clearance_mm_[block];
    if (block_min >= kCandidateReachMm) continue;
    block_min = std::numeric_limits<double>::infinity();
    const int end = std::min(node_count(), (block + 1) * kNodesPerChunk);
    for (int i = block * kNodesPerChunk; i < end; ++i) {
      if (!(probe_clearance_mm_[i] >= kCandidateReachMm)) query_node(probe, i);
      block_min = std::min(block_min, probe_clearance_mm_[i]);
    }
  }
}

void MsdsEngine::query_node(const ProbeCollider& probe, int node) {
  double& clearance = probe_clearance_mm_[node];
  clearance = probe.signed_distance_mm(position_[node]);
  if (!(clearance >= kCandidateReachMm)) candidate_nodes_.push_back(node);
}

void MsdsEngine::update_block_min_clearances() {
  for (int block = 0; block < node_chunk_count(); ++block) {
    const auto first = probe_clearance_mm_.begin() + block * kNodesPerChunk;
    const auto last =
        probe_clearance_mm_.begin() + std::min(node_count(), (block + 1) * kNodesPerChunk);
    block_min_clearance_mm_[block] = *std::min_element(first, last);
  }
}

void MsdsEngine::release_if_pulled_away(int node, const Eigen::Vector3d& force_mn) {
  // Signorini: the probe pushes and never pulls. A node inside the probe must be held; one merely
  // touching it whose springs pull it away from the probe (along the outward normal) is let go.
  // Only the node's own flag changes: safe inside a node-parallel pass.
  if (held_[node] && touching_only_[node] && force_mn.dot(contact_normal_[node]) > 0.0) {
    held_[node] = 0;
  }
}

Eigen::Vector3d MsdsEngine::spring_direction(int from, int to, double rest_length_mm,
                                             double& length_mm) const {
  const Eigen::Vector3d d = position_[to] - position_[from];
  length_mm = d.norm();
  if (length_mm > kCollapsedFraction * rest_length_mm) return d / length_mm;
  // Collapsed (or not finite): push apart along the rest direction.
  return (rest_[to] - rest_[from]) / rest_length_mm;
}

void MsdsEngine::gather_node_forces(int node, Eigen::Vector3d& elastic_mn,
                                    Eigen::Vector3d& damping_mn) const {
  elastic_mn.setZero();
  damping_mn.setZero();
  for (int e = adjacency_begin_[node]; e < adjacency_begin_[node + 1]; ++e) {
    const MsdsSpring& s = springs_[adjacency_spring_[e]];
    const int other = adjacency_other_[e];
    double length = 0.0;
    const Eigen::Vector3d dir = spring_direction(node, other, s.rest_length_mm, length);
    elastic_mn += s.stiffness_mn_per_mm * (length - s.rest_length_mm) * dir;
    damping_mn += s.damping_mn_s_per_mm * (velocity_[other] - velocity_[node]).dot(dir) * dir;
  }
  Eigen::Vector3d anchor_elastic, anchor_damping;
  anchor_force(node, anchor_elastic, anchor_damping);
  elastic_mn += anchor_elastic;
  damping_mn += anchor_damping;
}

double MsdsEngine::contact_force_n() const {
  // A held node does not accelerate: the probe balances its spring and damping forces exactly.
  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (const auto& c : contacts_) {
    if (!held_[c.node]) continue;
    Eigen::Vector3d elastic, damping;
    gather_node_forces(c.node, elastic, damping);
    total_mn += elastic + damping;
  }
  return total_mn.norm() / 1000.0;
}

int MsdsEngine::held_node_count() const {
  int held = 0;
  for (const auto& c : contacts_) held += held_[c.node];
  return held;
}

// ---------------------------------------------------------------------------------------------
// Explicit Euler (b).

MsdsEngine::StepResult MsdsEngine::explicit_euler_update(double dt_s) {
  // One pass over node blocks per task: each block's spring forces (SpringLattice), the contact
  // release, the update (it reads only its own nodes and writes the other float state buffer).
  for_each_chunk(explicit_->task_count(), [&](int task) { explicit_euler_task(task, dt_s); });
  explicit_->current = 1 - explicit_->current;
  return gather_update_result();
}

void MsdsEngine::explicit_euler_task(int task, double dt_s) {
  ExplicitKernel& k = *explicit_;
  msds_detail::SpringLattice::Sweep& sweep = k.sweeps[task];
  const msds_detail::FloatNodeState& state = k.state[k.current];
  msds_detail::FloatNodeState& next_state = k.state[1 - k.current];
  float* force_x = k.block_force[task].data();
  float* force_y = force_x + ExplicitKernel::kBlockForceStride;
  float* force_z = force_y + ExplicitKernel::kBlockForceStride;
  const msds_detail::ExplicitNodeArrays nodes{.x = position_.x.data(),
                                              .y = position_.y.data(),
                                              .z = position_.z.data(),
                                              .vx = velocity_.x.data(),
                                              .vy = velocity_.y.data(),
                                              .vz = velocity_.z.data(),
                                              .mass_kg = padded_mass_kg_.data(),
                                              .inverse_mass_per_kg = inverse_mass_per_kg_.data(),
                                              .probe_clearance_mm = probe_clearance_mm_.data()};
  k.lattice.start_sweep(sweep, state);
  for (int block = k.first_block[task]; block < k.first_block[task + 1]; ++block) {
    const int begin = block * kNodesPerChunk;
    const int end = std::min(node_count(), begin + kNodesPerChunk);
    k.lattice.block_forces(sweep, state, begin, end, force_x, force_y, force_z);
    if (!anchors_.empty()) add_anchor_forces(begin, end, force_x, force_y, force_z);
    settle_contacts(begin, end, force_x, force_y, force_z);
    // Forward Euler, as published: both updates use the state at the start of the step; the
    // position advances with the old velocity and the velocity with the old state's force.
    // Pinned nodes have no inverse mass and held ones no force: neither moves.
    const msds_detail::NodeUpdateSums sums = k.lattice.kernels().forward_euler(
        nodes, begin, end, dt_s, force_x, force_y, force_z, next_state);
    partial_a_[block] = sums.kinetic_energy_uj;
    partial_finite_[block] = sums.finite;
    block_min_clearance_mm_[block] = sums.min_probe_clearance_mm;
  }
}

void MsdsEngine::settle_contacts(int begin, int end, float* force_x, float* force_y,
                                 float* force_z) {
  auto c =
      std::lower_bound(contacts_.begin(), contacts_.end(), begin,
                       [](const NodeContact& contact, int node) { return contact.node < node; });
  for (; c != contacts_.end() && c->node < end; ++c) {
    const int i = c->node - begin;
    release_if_pulled_away(c->node, Eigen::Vector3d(force_x[i], force_y[i], force_z[i]));
    if (held_[c->node]) force_x[i] = force_y[i] = force_z[i] = 0.0f;
  }
}

void MsdsEngine::add_anchor_forces(int begin, int end, float* force_x, float* force_y,
                                   float* force_z) const {
  auto a =
      std::lower_bound(anchors_.begin(), anchors_.end(), begin,
                       [](const AnchorSpring& anchor, int node) { return anchor.node < node; });
  for (; a != anchors_.end() && a->node < end; ++a) {
    Eigen::Vector3d elastic, damping;
    anchor_force(*a, elastic, damping);
    const Eigen::Vector3d f = elastic + damping;
    const int i = a->node - begin;
    force_x[i] += static_cast<float>(f.x());
    force_y[i] += static_cast<float>(f.y());
    force_z[i] += static_cast<float>(f.z());
  }
}

void MsdsEngine::anchor_force(int node, Eigen::Vector3d& elastic_mn,
                              Eigen::Vector3d& damping_mn) const {
  if (anchor_of_node_[node] < 0) {
    elastic_mn.setZero();
    damping_mn.setZero();
    return;
  }
  anchor_force(anchors_[anchor_of_node_[node]], elastic_mn, damping_mn);
}

void MsdsEngine::anchor_force(const AnchorSpring& anchor, Eigen::Vector3d& elastic_mn,
                              Eigen::Vector3d& damping_mn) const {
  const int node = anchor.node;
  const double k = anchor.stiffness_mn_per_mm;
  elastic_mn = k * (anchor.target_mm - position_[node]);
  // Forward Euler needs the anchor damped like a spring (c = k β) or its mode grows; that drag on
  // the node's own velocity slows the seam (a pressed seam ends ~50 % further from one piece), so
  // the implicit integrator, stable without it, leaves the zero-length spring undamped (as
  // published).
  if (integrator_ == MsdsIntegrator::kExplicitEuler) {
    damping_mn = -k * settings_.damping_per_stiffness_s * velocity_[node];
  } else {
    damping_mn.setZero();
  }
}

double MsdsEngine::explicit_stable_time_step_s() const {
  return forward_euler_stable_time_step_s(
      msds_max_omega_squared_bound(rest_, springs_, mass_kg_,
                                   std::span(pinned_).first(rest_.size())),
      settings_.damping_per_stiffness_s);
}

void MsdsEngine::internal_forces_mn(Eigen::VectorXd& forces_mn) const {
  forces_mn.resize(3 * static_cast<Eigen::Index>(node_count()));
  for (int i = 0; i < node_count(); ++i) {
    Eigen::Vector3d elastic, damping;
    gather_node_forces(i, elastic, damping);
    forces_mn.segment<3>(3 * i) = elastic + damping;
  }
}

Eigen::SparseMatrix<double, Eigen::RowMajor> MsdsEngine::rest_stiffness_mn_per_mm() const {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(36 * springs_.size());
  for (const auto& s : springs_) {
    const Eigen::Vector3d n = (rest_[s.b] - rest_[s.a]) / s.rest_length_mm;
    const Eigen::Matrix3d k = s.stiffness_mn_per_mm * n * n.transpose();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        entries.emplace_back(3 * s.a + r, 3 * s.a + c, k(r, c));
        entries.emplace_back(3 * s.b + r, 3 * s.b + c, k(r, c));
        entries.emplace_back(3 * s.a + r, 3 * s.b + c, -k(r, c));
        entries.emplace_back(3 * s.b + r, 3 * s.a + c, -k(r, c));
      }
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> k(3 * node_count(), 3 * node_count());
  k.setFromTriplets(entries.begin(), entries.end());
  return k;
}

void MsdsEngine::tissue_forces_mn(Eigen::VectorXd& forces_mn) const {
  for (int i = 0; i < node_count(); ++i) {
    Eigen::Vector3d elastic = Eigen::Vector3d::Zero();
    for (int e = adjacency_begin_[i]; e < adjacency_begin_[i + 1]; ++e) {
      const MsdsSpring& s = springs_[adjacency_spring_[e]];
      double length = 0.0;
      const Eigen::Vector3d dir =
          spring_direction(i, adjacency_other_[e], s.rest_length_mm, length);
      elastic += s.stiffness_mn_per_mm * (length - s.rest_length_mm) * dir;
    }
    forces_mn.segment<3>(3 * i) = elastic;
  }
}

void MsdsEngine::displace_free_nodes_mm(const Eigen::VectorXd& du_mm) {
  for (int i = 0; i < node_count(); ++i) {
    if (!moves(i)) continue;
    const Eigen::Vector3d du = du_mm.segment<3>(3 * i);
    position_.set(i, position_[i] + du);
    // The bound on the node's distance to the probe holds for a node that moved at most this far.
    probe_clearance_mm_[i] -= du.lpNorm<1>();
  }
  update_block_min_clearances();
  sync_float_state();
  publish_state();
}

void MsdsEngine::move_held_node_mm(int node, const Eigen::Vector3d& position_mm) {
  if (pinned_[node] || !held_[node]) return;
  probe_clearance_mm_[node] -= (position_mm - position_[node]).lpNorm<1>();
  const int block = node / kNodesPerChunk;
  block_min_clearance_mm_[block] =
      std::min(block_min_clearance_mm_[block], probe_clearance_mm_[node]);
  position_.set(node, position_mm);
  if (explicit_) explicit_->state[explicit_->current].set(node, position_mm, velocity_[node]);
  x_[node] = position_mm;
  u_.segment<3>(3 * node) = position_mm - rest_[node];
}

double MsdsEngine::kinetic_energy_uj() const {
  double energy = 0.0;
  for (int i = 0; i < node_count(); ++i) energy += 0.5 * mass_kg_[i] * velocity_[i].squaredNorm();
  return energy;
}

double MsdsEngine::elastic_energy_uj() const {
  double energy = 0.0;
  for (const auto& s : springs_) {
    const double stretch = (position_[s.b] - position_[s.a]).norm() - s.rest_length_mm;
    energy += 0.5 * s.stiffness_mn_per_mm * stretch * stretch;
  }
  for (const auto& a : anchors_) {
    energy += 0.5 * a.stiffness_mn_per_mm * (a.target_mm - position_[a.node]).squaredNorm();
  }
  return energy;
}

int MsdsEngine::inverted_tet_count() const {
  int inverted = 0;
  for (const auto& t : tets_) {
    inverted += msds_detail::six_signed_volume(position_.x.data(), position_.y.data(),
                                               position_.z.data(), t) <= 0.0;
  }
  return inverted;
}

}  // namespace ultrasim::sim
