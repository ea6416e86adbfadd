// ExactFem against CalculiX (ccx) on the identical mesh, materials, fixed nodes, loads and
// prescribed displacements: an independent FEM code, so agreement checks our element stiffness,
// assembly, constraint handling and units together.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdio>
#include <string>
#include <vector>

#include "calculix_io.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace ultrasim::sim::test {
namespace {

using geometry::GridSpec;

struct Bar {
  geometry::TetMesh mesh;
  std::vector<Material> materials;
  std::vector<std::uint8_t> fixed;
  std::vector<int> end_face;  // nodes on x = 50
};

// A 50 × 30 × 30 mm block on a 6 × 4 × 4 node grid, fixed on x = 0, two materials (stiffer
// where z > 15) so per-tet material handling is exercised.
Bar make_bar() {
  Bar b;
  b.mesh = geometry::make_grid_tet_mesh(
      GridSpec::spanning(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(50, 30, 30), {6, 4, 4}));
  const auto& p = b.mesh.rest_positions_mm;
  for (const auto& t : b.mesh.tets) {
    EXPECT_GT(geometry::signed_tet_volume(p[t[0]], p[t[1]], p[t[2]], p[t[3]]), 0.0);
    const double z = (p[t[0]] + p[t[1]] + p[t[2]] + p[t[3]]).z() / 4.0;
    b.materials.push_back(z > 15.0 ? Material{2, "muscle", 80.0, 0.42}
                                   : Material{1, "fat", 25.0, 0.47});
  }
  b.fixed.assign(p.size(), 0);
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    b.fixed[n] = p[n].x() == 0.0;
    if (p[n].x() == 50.0) b.end_face.push_back(n);
  }
  return b;
}

double relative_max_error(const ExactFem& fem, const std::vector<Eigen::Vector3d>& reference) {
  double err = 0.0, scale = 0.0;
  for (int n = 0; n < fem.node_count(); ++n) {
    err = std::max(err, (fem.displacement_mm(n) - reference[n]).cwiseAbs().maxCoeff());
    scale = std::max(scale, reference[n].cwiseAbs().maxCoeff());
  }
  return err / scale;
}

// ccx prints displacements with 7 significant digits (e13.6): errors near 3e-7 are that rounding.
std::string format_error(double err) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2e", err);
  return text;
}

TEST(CalculixComparison, NodalLoadsOnTheFreeEnd) {
  ASSERT_TRUE(calculix_available())
      << "ccx (CalculiX) not found on PATH: run scripts/install-deps.sh (Debian calculix-ccx)";
  const Bar b = make_bar();
  CalculixProblem problem{&b.mesh, b.materials, b.fixed, {}, {}};
  ExactFem fem(b.mesh, b.materials, b.fixed);
  for (std::size_t i = 0; i < b.end_face.size(); ++i) {
    // Bending down, a little stretch and twist: every component loaded, varying over the face.
    const Eigen::Vector3d force_mn(40.0 + 5.0 * static_cast<double>(i % 3), -15.0,
                                   -120.0 + 7.0 * static_cast<double>(i));
    problem.loads.push_back({b.end_face[i], force_mn});
    fem.set_nodal_load(b.end_face[i], force_mn);
  }
  const auto stats = fem.solve(std::span<const PrescribedNode>{});
  EXPECT_EQ(stats.contact_nodes, 0);
  const auto reference = solve_with_calculix(problem);
  const double err = relative_max_error(fem, reference);
  EXPECT_LE(err, 1e-6);
  RecordProperty("relative_max_error", format_error(err));
}

TEST(CalculixComparison, PrescribedDisplacementsWithLoads) {
  ASSERT_TRUE(calculix_available())
      << "ccx (CalculiX) not found on PATH: run scripts/install-deps.sh (Debian calculix-ccx)";
  const Bar b = make_bar();
  CalculixProblem problem{&b.mesh, b.materials, b.fixed, {}, {}};
  ExactFem fem(b.mesh, b.materials, b.fixed);
  // Hold every other end-face node at a displacement (a probe-like push), load a top-face node.
  for (std::size_t i = 0; i < b.end_face.size(); i += 2) {
    problem.held.push_back(
        {b.end_face[i], Eigen::Vector3d(-0.8, 0.1 * static_cast<double>(i % 4), -1.5)});
  }
  int top = -1;
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (b.mesh.rest_positions_mm[n].isApprox(Eigen::Vector3d(30, 10, 30))) top = n;
  ASSERT_GE(top, 0);
  problem.loads.push_back({top, Eigen::Vector3d(0, 0, -50.0)});
  fem.set_nodal_load(top, problem.loads.back().force_mn);
  const auto stats = fem.solve(problem.held);
  EXPECT_EQ(stats.contact_nodes, static_cast<int>(problem.held.size()));
  const auto reference = solve_with_calculix(problem);
  const double err = relative_max_error(fem, reference);
  EXPECT_LE(err, 1e-6);
  RecordProperty("relative_max_error", format_error(err));
}

}  // namespace
}  // namespace ultrasim::sim::test
