// The stitched volume's fine correction: on one piece it is the solve of the free nodes' balance
// (checked against Eigen's sparse LDLT of the same system), and a stitched PCG FEM under a probe
// put down where four sub-volumes meet is within 2 % of one piece ten frames later with it, not
// with the seams alone (issue 5's target).

#include "ultrasim/sim/fine_correction.hpp"

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <span>
#include <vector>

#include "slab_region.hpp"
#include "sliding_reference.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {
namespace {

using Region = testing::SlabRegion;
using testing::max_norm;
constexpr auto make_region = testing::make_fat_over_muscle_slab;

// The fine correction of a region in one piece: every grid node is the engine's own node, and
// `built` gives the stiffness.
FineCorrection one_piece_correction(const DeformationEngine& built,
                                    std::span<const std::uint8_t> fixed) {
  std::vector<int> grid_nodes(fixed.size());
  std::iota(grid_nodes.begin(), grid_nodes.end(), 0);
  const std::vector<std::vector<int>> maps{grid_nodes};
  const std::vector<const DeformationEngine*> engines{&built};
  return FineCorrection(maps, engines, fixed);
}

TEST(FineCorrection, OnOnePieceItSolvesTheFreeNodesBalance) {
  const Region r = make_region({7, 6, 5});
  LinearFem fem(r.mesh, r.materials, r.fixed, FemSettings{});
  const int n = r.mesh.node_count();
  Eigen::VectorXd u(3 * n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = r.mesh.rest_positions_mm[i];
    u.segment<3>(3 * i) = r.fixed[i] ? Eigen::Vector3d::Zero()
                                     : Eigen::Vector3d(0.1 * std::sin(p.x()), 0.05 * p.y(), 0.3);
  }
  fem.set_displacements_mm(u);
  const int held[] = {r.grid.node_index(3, 2, 0), r.grid.node_index(4, 2, 0)};
  for (int h : held) fem.prescribe_displacement(h, fem.displacement_mm(h));

  // The reference: K_ff u_f = −K_fh u_h with the fixed and held nodes where they are.
  std::vector<int> free_dofs;
  for (int i = 0; i < n; ++i) {
    if (!fem.holds_node(i)) {
      for (int d = 0; d < 3; ++d) free_dofs.push_back(3 * i + d);
    }
  }
  const Eigen::MatrixXd k = Eigen::MatrixXd(fem.stiffness());
  const auto f = static_cast<Eigen::Index>(free_dofs.size());
  Eigen::MatrixXd kff(f, f);
  Eigen::VectorXd rhs(f);
  Eigen::VectorXd u_held = fem.displacements_mm();
  for (int dof : free_dofs) u_held[dof] = 0.0;
  const Eigen::VectorXd pull = -(k * u_held);
  for (Eigen::Index a = 0; a < f; ++a) {
    rhs[a] = pull[free_dofs[a]];
    for (Eigen::Index b = 0; b < f; ++b) kff(a, b) = k(free_dofs[a], free_dofs[b]);
  }
  const Eigen::SparseMatrix<double> kff_sparse = kff.sparseView();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(kff_sparse);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd expected_free = ldlt.solve(rhs);

  const LinearFem fresh(r.mesh, r.materials, r.fixed, FemSettings{});
  FineCorrection fine = one_piece_correction(fresh, r.fixed);
  const std::vector<DeformationEngine*> engines{&fem};
  const std::vector<std::uint8_t> stepped{1};
  const FineCorrection::Result result = fine.correct(engines, stepped, 2000, 1e-12, {}, nullptr);
  EXPECT_LT(result.relative_residual, 1e-12);
  EXPECT_GT(result.largest_move_mm, 0.1);
  const Eigen::VectorXd after = fem.displacements_mm();
  for (Eigen::Index a = 0; a < f; ++a) {
    EXPECT_NEAR(after[free_dofs[a]], expected_free[a], 1e-8) << free_dofs[a];
  }
  for (int h : held) EXPECT_EQ(fem.displacement_mm(h), u.segment<3>(3 * h));
  for (int i = 0; i < n; ++i) {
    if (r.fixed[i]) {
      EXPECT_EQ(fem.displacement_mm(i), Eigen::Vector3d::Zero());
    }
  }
}

// Nodes the probe holds along its normal only (the PCG FEM's Coulomb slip) move in their tangent
// planes, against their friction: on one piece the correction reaches the frame's equilibrium
// with them free there, as a fresh factorisation of that reduced problem gives it.
TEST(FineCorrection, OnOnePieceItSlidesTheSlidingNodesInTheirTangentPlanes) {
  const Region r = make_region({12, 10, 6});
  FemSettings settings;
  settings.pcg_iterations_per_frame = 2;  // far from settled: the correction has work to do
  settings.contact = {HeldContactModel::kCoulombSlip, 0.1};
  LinearFem fem(r.mesh, r.materials, r.fixed, settings);
  for (int frame = 0; frame < 4; ++frame) {
    // Pressed, then moved along x: some held nodes slide against friction, some stick.
    const double x = frame < 2 ? 11.0 : 13.0;
    const ProbeCollider probe =
        ProbeCollider::sphere(SphereCollider{Eigen::Vector3d(x, 9.0, 2.0 - 8.0), 8.0});
    fem.step(&probe, 1.0 / 60);
  }
  int sliding = 0, with_friction = 0;
  for (int n = 0; n < fem.node_count(); ++n) {
    sliding += fem.sliding_hold(n) != nullptr;
    with_friction += fem.sliding_hold(n) != nullptr && fem.sliding_hold(n)->friction_mn.norm() > 0;
  }
  ASSERT_GT(with_friction, 2) << sliding << " sliding";
  const Eigen::VectorXd expected = testing::constrained_equilibrium(fem);

  FineCorrection fine = one_piece_correction(fem, r.fixed);
  const std::vector<DeformationEngine*> engines{&fem};
  const std::vector<std::uint8_t> stepped{1};
  const FineCorrection::Result result = fine.correct(engines, stepped, 4000, 1e-13, {}, nullptr);
  EXPECT_LT(result.relative_residual, 1e-13);
  EXPECT_GT(result.largest_move_mm, 0.01);
  const double peak = expected.cwiseAbs().maxCoeff();
  ASSERT_GT(peak, 1.0);
  EXPECT_LT((fem.displacements_mm() - expected).cwiseAbs().maxCoeff(), 1e-8 * peak);
}

// The corotational FEM's force is the pull of its tets with the rotations they hold, b − K_R u:
// its correction must solve with K_R. Bent 0.6 rad at the top so its tets turn, stepped once
// (every tet takes its rotation, one CG iteration: far from settled), the correction run to
// convergence leaves no force on a free node. With the rest stiffness instead it converged to
// K's answer, and the free nodes' force rose from 0.73 to 1.94 times the load (the large case's
// 13 mm presses with 10 iterations a frame: seams torn at 4.5 s, the press refused thereafter).
TEST(FineCorrection, OnOnePieceOfTheCorotationalFemItSolvesWithTheWarpedStiffness) {
  const Region r = make_region({12, 10, 6});
  CorotationalSettings settings;
  settings.rotation_update_tolerance = 0.0;
  settings.max_rotation_updates_fraction = 1.0;
  settings.pcg_iterations_per_frame = 1;
  CorotationalFem fem(r.mesh, r.materials, r.fixed, settings);
  const int n = r.mesh.node_count();
  const double deepest = 2.0 * (r.grid.nodes.z() - 1);
  Eigen::VectorXd u(3 * n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = r.mesh.rest_positions_mm[i];
    const double turn = 0.6 * (deepest - p.z()) / deepest;  // rad, about y, 0 at the base
    const Eigen::Vector3d centre(11.0, p.y(), deepest);
    u.segment<3>(3 * i) =
        Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitY()) * (p - centre) + centre - p;
  }
  fem.set_displacements_mm(u);
  fem.step(nullptr, 1.0 / 60);
  // The tets have turned: K_R is not K.
  Eigen::VectorXd warped(3 * n);
  ASSERT_TRUE(fem.tangent_stiffness_times(u, warped));
  const Eigen::VectorXd rest = fem.rest_stiffness_mn_per_mm() * u;
  ASSERT_GT((warped - rest).norm(), 0.1 * rest.norm());

  Eigen::VectorXd forces(3 * n);
  fem.tissue_forces_mn(forces);
  const double load = forces.norm();
  const auto free_force = [&] {
    fem.tissue_forces_mn(forces);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      if (!fem.holds_node(i)) sum += forces.segment<3>(3 * i).squaredNorm();
    }
    return std::sqrt(sum);
  };
  const double before = free_force();
  ASSERT_GT(before, 1e-3 * load);
  FineCorrection fine = one_piece_correction(fem, r.fixed);
  const std::vector<DeformationEngine*> engines{&fem};
  const std::vector<std::uint8_t> stepped{1};
  const FineCorrection::Result result = fine.correct(engines, stepped, 4000, 1e-13, {}, nullptr);
  EXPECT_LT(result.relative_residual, 1e-13);
  EXPECT_LT(free_force(), 1e-10 * load) << "before " << before / load << " of the load";
}

TEST(FineCorrection, StopsWhenTheFrameHasNoTimeLeft) {
  const Region r = make_region({7, 6, 5});
  LinearFem fem(r.mesh, r.materials, r.fixed, FemSettings{});
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * r.mesh.node_count());
  for (int i = 0; i < r.mesh.node_count(); ++i) {
    if (!r.fixed[i]) u[3 * i + 2] = 0.5;
  }
  fem.set_displacements_mm(u);
  FineCorrection fine = one_piece_correction(fem, r.fixed);
  const std::vector<DeformationEngine*> engines{&fem};
  const std::vector<std::uint8_t> stepped{1};
  int asked = 0;
  const auto time_left = [&asked] { return ++asked <= 2; };  // time for two iterations
  EXPECT_EQ(fine.correct(engines, stepped, 100, 1e-12, time_left, nullptr).iterations, 2);
  const auto no_time = [] { return false; };
  EXPECT_EQ(fine.correct(engines, stepped, 100, 1e-12, no_time, nullptr).iterations, 0);
  // Nothing stepped, nothing moves.
  const Eigen::VectorXd before = fem.displacements_mm();
  const std::vector<std::uint8_t> none{0};
  EXPECT_EQ(fine.correct(engines, none, 100, 1e-12, {}, nullptr).iterations, 0);
  EXPECT_EQ(fem.displacements_mm(), before);
}

// Issue 5's target: a probe put down 3 mm deep where four sub-volumes meet and held still; ten
// frames later the stitched PCG FEM (selective, seams exchanged once a frame) is within 2 % of
// one piece (max norm, over the largest one-piece displacement) with the fine correction, and
// far from it with the seams alone. Under the default frictionless Coulomb slip (measured 0.29 %
// against 25 %; the correction moves the sliding nodes in their tangent planes) and under the
// published stick contact (0.09 % against 19 %). With friction (not the default) the answer
// depends on the path and the two reach different ones (3.2 % with μ 0.1, docs/accuracy.md).
TEST(FineCorrection, AStitchedPcgFemTenFramesAfterAPlacedProbeIsWithinTwoPercentOfOnePiece) {
  const Region r = make_region({30, 30, 8});
  hal::InlineJobSystem jobs;
  for (const EngineSettings& engines :
       {ultrasim::testing::with_held_contact(HeldContactModel::kCoulombSlip, 0.0),
        testing::stick_contact()}) {
    const auto contact = engines.fem.contact.model == HeldContactModel::kStick ? "stick" : "slip";
    LinearFem one_piece(r.mesh, r.materials, r.fixed, engines.fem);
    // Grid nodes 14 and 15 are both sub-volumes' copies on x and y: the probe's centre is there.
    const ProbeCollider probe =
        ProbeCollider::sphere(SphereCollider{Eigen::Vector3d(29.0, 29.0, 3.0 - 8.0), 8.0});
    for (int f = 0; f < 10; ++f) one_piece.step(&probe, 1.0 / 60);
    const double peak = max_norm(one_piece.displacements_mm());
    ASSERT_GT(peak, 2.0) << contact;
    double error[2] = {0.0, 0.0};
    for (const int iterations : {0, 20}) {
      StitchingSettings stitching{.sub_volumes = {2, 2, 1}};
      stitching.fine_correction_iterations = iterations;
      StitchedVolume stitched(r.grid, r.materials, r.fixed, EngineKind::kPcgFem, engines, stitching,
                              &jobs);
      int first_frame_iterations = 0;
      for (int f = 0; f < 10; ++f) {
        stitched.step(&probe, 1.0 / 60);
        if (f == 0) first_frame_iterations = stitched.last_stitch_stats().fine_iterations;
      }
      error[iterations > 0] =
          max_norm(stitched.displacements_mm() - one_piece.displacements_mm()) / peak;
      if (iterations > 0) {
        // All of them at first; none once the tissue has settled (an imbalance under 1e-3 of
        // the load), so a still probe costs nothing: within a few frames more, while the seams'
        // remembered loads catch up with what the springs carry (one iteration a frame until
        // then).
        EXPECT_EQ(first_frame_iterations, iterations) << contact;
        int settled_after = 10;
        while (stitched.last_stitch_stats().fine_iterations > 0 && settled_after < 60) {
          stitched.step(&probe, 1.0 / 60);
          ++settled_after;
        }
        EXPECT_EQ(stitched.last_stitch_stats().fine_iterations, 0)
            << contact << " after " << settled_after << " frames";
        for (int f = 0; f < 10; ++f) {  // and stays settled
          stitched.step(&probe, 1.0 / 60);
          EXPECT_EQ(stitched.last_stitch_stats().fine_iterations, 0) << contact << ", frame " << f;
        }
        std::printf("%s: settled after %d frames\n", contact, settled_after);
      }
    }
    EXPECT_LT(error[1], 0.02) << contact << ": fine correction " << error[1] << ", seams alone "
                              << error[0];
    EXPECT_GT(error[0], 0.05) << contact << ": seams alone " << error[0];
  }
}

// The corotational FEM's rotations change its stiffness under the press; the correction solves
// with its warped stiffness against the forces at the rotations the tets hold, and settles the
// four sub-volumes around the probe together (under the default slip, as above).
TEST(FineCorrection,
     AStitchedCorotationalFemTenFramesAfterAPlacedProbeIsWithinTwoPercentOfOnePiece) {
  const Region r = make_region({30, 30, 8});
  hal::InlineJobSystem jobs;
  const EngineSettings engines =
      ultrasim::testing::with_held_contact(HeldContactModel::kCoulombSlip, 0.0);
  CorotationalFem one_piece(r.mesh, r.materials, r.fixed, engines.corotational);
  const ProbeCollider probe =
      ProbeCollider::sphere(SphereCollider{Eigen::Vector3d(29.0, 29.0, 3.0 - 8.0), 8.0});
  for (int f = 0; f < 10; ++f) one_piece.step(&probe, 1.0 / 60);
  const double peak = max_norm(one_piece.displacements_mm());
  ASSERT_GT(peak, 2.0);
  double error[2] = {0.0, 0.0};
  for (const int iterations : {0, 20}) {
    StitchingSettings stitching{.sub_volumes = {2, 2, 1}};
    stitching.fine_correction_iterations = iterations;
    StitchedVolume stitched(r.grid, r.materials, r.fixed, EngineKind::kCorotationalFem, engines,
                            stitching, &jobs);
    for (int f = 0; f < 10; ++f) stitched.step(&probe, 1.0 / 60);
    error[iterations > 0] =
        max_norm(stitched.displacements_mm() - one_piece.displacements_mm()) / peak;
  }
  EXPECT_LT(error[1], 0.02) << "fine correction " << error[1] << ", seams alone " << error[0];
  EXPECT_GT(error[0], 0.05) << "seams alone " << error[0];
  std::printf("corotational: seams alone %.1f %%, fine correction %.2f %%\n", 100 * error[0],
              100 * error[1]);
}

}  // namespace
}  // namespace ultrasim::sim
