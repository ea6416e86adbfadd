// ExactFem's frictionless probe contact against Hertz's law: a rigid sphere pressed step by step
// into a large block (a half-space) on a refinement sequence of graded meshes.
//
// Hertz: a rigid sphere of radius R pressed to depth d into an elastic half-space, frictionless,
//   F = 4/3 · E/(1 − ν²) · √R · d^(3/2),  contact radius a = √(R d),  for d/R ≤ 0.05.
//
// What separates the FEM from Hertz on these meshes (numbers for the finest one, d/R in
// [0.02, 0.05]; the table is printed to the log):
//   - linear tets are too stiff, in the contact zone and in the graded far field; the error
//     falls with refinement (the fit below: +15.4, +6.8, +5.4, +4.5 % on the four levels);
//   - the node-to-sphere contact is resolved ring by ring of skin nodes: while no new ring comes
//     into contact F grows linearly in d, so the error zigzags by about ±2 % at a/h ≈ 2-3;
//   - the engine's contact is geometrically exact where Hertz linearises: nodes are kept out of
//     the sphere at their displaced positions (they move towards the axis, where the sphere is
//     deeper) and pushed along the sphere's normals, not along z; an O(a/R) effect. Measured
//     once on the finest mesh with Hertz's linearised contact instead (ExactFem::solve with
//     vertical planes at d − r²/2R through the rest positions, own active set): 1.5 % (d/R =
//     0.02) to 2.0 % (d/R = 0.05) less force than step(), +1.1 to +5.1 % against Hertz;
//   - the block is finite (estimated: its fixed base 100 a_max down stiffens it by ~1 %, its
//     free sides 60 a_max out soften it by about as much), and a sphere is not Hertz's paraboloid
//     (−0.2 to −0.6 %).
// Small d is under-resolved (at d/R = 0.01 the contact is 13 nodes on the finest mesh, 1 on the
// coarsest), so the force is checked against Hertz for d/R in [0.02, 0.05] only.
//
// Cost: the finest mesh (146k nodes; ~60 s alone, ~4.8 GB at its peak) dominates. It is within
// 5 % of Hertz on the fit (+4.5 %) and at every depth from d/R = 0.02 to 0.05 (+3.1 to +4.9 %).

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "graded_block.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace ultrasim::sim {
namespace {

constexpr double kRadiusMm = 20.0;
constexpr double kYoungsKpa = 30.0;
constexpr double kPoisson = 0.3;  // far from 0.5: linear tets lock when nearly incompressible
constexpr int kFrames = 10;       // d/R = 0.005, 0.010, … 0.050, pressed in that order
constexpr double kDepthStepRatio = 0.005;
constexpr double kMinCheckedDepthRatio = 0.02;  // below it the contact is a handful of nodes
const double kMaxContactRadiusMm = kRadiusMm * std::sqrt(kFrames * kDepthStepRatio);

double hertz_force_mn(double depth_mm) {
  return 4.0 / 3.0 * kYoungsKpa / (1.0 - kPoisson * kPoisson) * std::sqrt(kRadiusMm) *
         std::pow(depth_mm, 1.5);
}

struct Frame {
  double depth_mm = 0.0;
  double force_mn = 0.0;          // the engine's contact force
  double support_force_mn = 0.0;  // the fixed base's reaction, along +z
  int contact_nodes = 0;
  int contact_rounds = 0;
  double contact_radius_mm = 0.0;       // largest distance of a constrained node from the axis
  double min_normal_force_mn = 0.0;     // smallest push along the sphere's normal at a contact
  double max_tangential_ratio = 0.0;    // largest |tangential| / |force| at a contact
  double max_contact_gap_mm = 0.0;      // largest distance of a contact from the sphere
  double min_signed_distance_mm = 0.0;  // over all free nodes: < 0 inside the sphere
  double max_free_residual_mn = 0.0;    // largest |K u| at a free node not in contact
  int inverted_tets = 0;
  bool diverged = false;

  double relative_error() const { return force_mn / hertz_force_mn(depth_mm) - 1.0; }
  bool checked() const { return depth_mm >= (kMinCheckedDepthRatio - 1e-9) * kRadiusMm; }
};

struct Level {
  double fineness = 0.0;
  int nodes = 0;
  double core_spacing_mm = 0.0;
  double seconds = 0.0;
  std::vector<Frame> frames;

  // Least-squares fit of F = C d^(3/2) over the checked depths, relative to Hertz's C: the error
  // with the ring-by-ring zigzag averaged out.
  double fit_error() const {
    double fh = 0.0, hh = 0.0;
    for (const auto& f : frames) {
      if (!f.checked()) continue;
      fh += f.force_mn * hertz_force_mn(f.depth_mm);
      hh += hertz_force_mn(f.depth_mm) * hertz_force_mn(f.depth_mm);
    }
    return fh / hh - 1.0;
  }
};

// The block: skin at z = 0, fixed at z = 100 a_max, sides at ±60 a_max (a_max: the contact
// radius at d/R = 0.05). The skin is meshed uniformly out to 1.25 a_max with spacing
// a_max / (3 · fineness), to the same depth; beyond, spacing grows geometrically by 1.2 per
// element laterally and 1.35 in depth, each ratio raised to 1/fineness: a finer level splits
// every element of the coarser map, far field included.
Level run_level(double fineness) {
  const auto start = std::chrono::steady_clock::now();
  const double a = kMaxContactRadiusMm;
  const double h = a / (3.0 * fineness);
  const auto lateral = testing::graded_axis(h, 1.25 * a, 60.0 * a, std::pow(1.2, 1.0 / fineness));
  const auto xy = testing::mirrored(lateral);
  const auto z = testing::graded_axis(h, 1.25 * a, 100.0 * a, std::pow(1.35, 1.0 / fineness));
  const testing::GradedBlock b = testing::make_graded_block(xy, xy, z);
  const auto& rest = b.mesh.rest_positions_mm;
  int non_positive = 0;
  for (const auto& t : b.mesh.tets) {
    non_positive +=
        geometry::signed_tet_volume(rest[t[0]], rest[t[1]], rest[t[2]], rest[t[3]]) <= 0;
  }
  EXPECT_EQ(non_positive, 0) << "fineness " << fineness;
  const std::vector<Material> materials(b.mesh.tets.size(),
                                        Material{1, "tissue", kYoungsKpa, kPoisson});
  // The skin the sphere can reach: its Green's functions are precomputed in blocks of solves,
  // cheaper than three solves per node as each comes into contact.
  std::vector<std::uint8_t> candidates(rest.size(), 0);
  for (std::size_t n = 0; n < rest.size(); ++n) {
    candidates[n] = rest[n].z() == 0.0 && rest[n].head<2>().norm() <= 1.1 * a + h;
  }
  ExactFem fem(b.mesh, materials, b.fixed, {}, candidates);

  Level level;
  level.fineness = fineness;
  level.nodes = b.mesh.node_count();
  level.core_spacing_mm = h;
  std::vector<std::uint8_t> in_contact(rest.size(), 0);
  for (int k = 1; k <= kFrames; ++k) {
    Frame f;
    f.depth_mm = k * kDepthStepRatio * kRadiusMm;
    // The sphere's lowest point at depth d on the axis; it pushes along +z.
    const Eigen::Vector3d centre(0.0, 0.0, f.depth_mm - kRadiusMm);
    const ProbeCollider probe = ProbeCollider::sphere(SphereCollider{centre, kRadiusMm});
    const EngineStepStats stats = fem.step(&probe, 0.0);
    f.force_mn = 1e3 * stats.contact_force_n;
    f.contact_nodes = stats.contact_nodes;
    f.contact_rounds = fem.last_solve_stats().contact_rounds;
    f.inverted_tets = stats.inverted_tets;
    f.diverged = stats.diverged;
    const auto deformed = fem.deformed_positions_mm();
    f.min_normal_force_mn = 1e300;
    std::fill(in_contact.begin(), in_contact.end(), 0);
    for (int n : fem.constrained_nodes()) {
      in_contact[n] = 1;
      const Eigen::Vector3d& p = deformed[n];
      f.contact_radius_mm = std::max(f.contact_radius_mm, p.head<2>().norm());
      f.max_contact_gap_mm = std::max(f.max_contact_gap_mm, probe.signed_distance_mm(p));
      const Eigen::Vector3d normal = (p - centre).normalized();  // the sphere's, into the tissue
      const Eigen::Vector3d r = fem.reaction_force_mn(n);
      f.min_normal_force_mn = std::min(f.min_normal_force_mn, r.dot(normal));
      f.max_tangential_ratio =
          std::max(f.max_tangential_ratio, (r - r.dot(normal) * normal).norm() / r.norm());
    }
    f.min_signed_distance_mm = 1e300;
    for (std::size_t n = 0; n < rest.size(); ++n) {
      const Eigen::Vector3d r = fem.reaction_force_mn(static_cast<int>(n));
      if (b.fixed[n]) {
        f.support_force_mn -= r.z();  // the base holds the block up against the push
        continue;
      }
      f.min_signed_distance_mm =
          std::min(f.min_signed_distance_mm, probe.signed_distance_mm(deformed[n]));
      if (!in_contact[n]) f.max_free_residual_mn = std::max(f.max_free_residual_mn, r.norm());
    }
    level.frames.push_back(f);
  }
  level.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return level;
}

std::string report(const std::vector<Level>& levels) {
  std::string out;
  char line[160];
  std::snprintf(line, sizeof line,
                "Hertz: R = %g mm, E = %g kPa, nu = %g; error = F_FEM / F_Hertz - 1\n", kRadiusMm,
                kYoungsKpa, kPoisson);
  out += line;
  out +=
      "level  nodes   h_mm a_max/h   d/R   F_FEM_mN F_Hertz_mN    error contacts a_FEM_mm "
      "a_Hertz_mm\n";
  for (std::size_t i = 0; i < levels.size(); ++i) {
    const Level& l = levels[i];
    for (const auto& f : l.frames) {
      std::snprintf(line, sizeof line,
                    "%5zu %6d %6.3f %7.2f %5.3f %10.3f %10.3f %+7.2f%% %8d %8.3f %10.3f\n", i + 1,
                    l.nodes, l.core_spacing_mm, kMaxContactRadiusMm / l.core_spacing_mm,
                    f.depth_mm / kRadiusMm, f.force_mn, hertz_force_mn(f.depth_mm),
                    100.0 * f.relative_error(), f.contact_nodes, f.contact_radius_mm,
                    std::sqrt(kRadiusMm * f.depth_mm));
      out += line;
    }
  }
  for (std::size_t i = 0; i < levels.size(); ++i) {
    std::snprintf(line, sizeof line,
                  "level %zu: fit of F = C d^1.5 over d/R in [%.2f, 0.05]: error %+.2f%%; "
                  "%.1f s\n",
                  i + 1, kMinCheckedDepthRatio, 100.0 * levels[i].fit_error(), levels[i].seconds);
    out += line;
  }
  return out;
}

// Every frame of a level: the contact's mechanics, whatever the resolution.
void expect_frictionless_unilateral_and_balanced(const Level& l) {
  double last_force = 0.0;
  for (const auto& f : l.frames) {
    SCOPED_TRACE("fineness " + std::to_string(l.fineness) +
                 ", d/R = " + std::to_string(f.depth_mm / kRadiusMm));
    EXPECT_FALSE(f.diverged);
    EXPECT_EQ(f.inverted_tets, 0);
    EXPECT_LT(f.contact_rounds, ExactFemSettings{}.max_contact_rounds);  // the set settled
    ASSERT_GT(f.contact_nodes, 0);
    EXPECT_GT(f.force_mn, last_force);
    last_force = f.force_mn;
    // Unilateral: every contact is pushed, none pulled, and no node is inside the sphere.
    EXPECT_GT(f.min_normal_force_mn, 0.0);
    EXPECT_GT(f.min_signed_distance_mm, -1e-6);
    // Contacts lie on the sphere: they slide on tangent planes, re-projected beyond 10 µm.
    EXPECT_LT(f.max_contact_gap_mm, 0.01);
    // Frictionless: the force on a contact is along the sphere's normal. Its direction is the
    // normal where the frame's rows were set up; the node slides on within the frame, a few
    // hundredths of a millimetre (measured ≤ 1.3e-3 relative).
    EXPECT_LT(f.max_tangential_ratio, 5e-3);
    // The base carries the push; free nodes are in balance (the field is stored in float).
    EXPECT_NEAR(f.support_force_mn, f.force_mn, 1e-6 * f.force_mn);
    EXPECT_LT(f.max_free_residual_mn, 1e-5 * f.force_mn);
    // Nodal contact: the edge lies between the outermost ring held and the next one out, rings
    // of the uniform core being less than a spacing apart (measured within 0.82 h everywhere).
    EXPECT_NEAR(f.contact_radius_mm, std::sqrt(kRadiusMm * f.depth_mm), 1.5 * l.core_spacing_mm);
  }
}

// One test, so that one process builds and factors the meshes (gtest_discover_tests runs every
// TEST in a process of its own). Four levels, each splitting the elements of the one before by
// 3/2, 4/3 and 3/2.
TEST(HertzContact, SpherePressedIntoGradedBlocksConvergesToHertz) {
  std::vector<Level> l;
  for (double fineness : {0.5, 0.75, 1.0, 1.5}) l.push_back(run_level(fineness));
  std::cout << report(l) << std::flush;
  for (std::size_t i = 0; i < l.size(); ++i) {
    RecordProperty("fit_error_pct_level_" + std::to_string(i + 1),
                   std::to_string(100.0 * l[i].fit_error()));
    expect_frictionless_unilateral_and_balanced(l[i]);
  }
  // Every refinement brings the FEM closer to Hertz: on the fit (zigzag averaged out) and at the
  // deepest frame, where the contact is best resolved (measured +15.4, +6.8, +5.4, +4.5 % and
  // +16.7, +8.5, +5.4, +4.9 %).
  for (std::size_t i = 1; i < l.size(); ++i) {
    EXPECT_LT(std::abs(l[i].fit_error()), std::abs(l[i - 1].fit_error())) << "level " << i + 1;
    EXPECT_LT(std::abs(l[i].frames.back().relative_error()),
              std::abs(l[i - 1].frames.back().relative_error()))
        << "level " << i + 1;
  }
  // The finest level against Hertz where the contact is resolved (see the top of the file for
  // what the remaining few percent are): within 5 % on the fit and at every depth from
  // d/R = 0.02 to 0.05.
  const Level& finest = l.back();
  EXPECT_LT(std::abs(finest.fit_error()), 0.05);
  for (const auto& f : finest.frames) {
    if (!f.checked()) continue;
    EXPECT_LT(std::abs(f.relative_error()), 0.05) << "d/R = " << f.depth_mm / kRadiusMm;
  }
}

}  // namespace
}  // namespace ultrasim::sim
