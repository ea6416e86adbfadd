// The stitched volume's coarse correction: the coarse step against one written out here with
// dense matrices, the engines' side of it, and what it does to a stitched region's relaxation.

#include "ultrasim/sim/coarse_correction.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "slab_region.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/msds.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {
namespace {

using Region = testing::SlabRegion;
using testing::max_norm;
constexpr auto make_region = testing::make_fat_over_muscle_slab;

// A smooth field, largest at the skin, zero at the fixed base.
Eigen::VectorXd smooth_field(const Region& r) {
  Eigen::VectorXd u(3 * r.mesh.node_count());
  const double depth = 2.0 * (r.grid.nodes.z() - 1);
  for (int n = 0; n < r.mesh.node_count(); ++n) {
    const Eigen::Vector3d p = r.mesh.rest_positions_mm[n];
    u.segment<3>(3 * n) = Eigen::Vector3d(0.3, 0.2, 1.0) * (1.0 - p.z() / depth) *
                          std::sin(p.x() / 13.0 + 0.3) * std::cos(p.y() / 17.0);
  }
  return u;
}

TEST(CoarseCorrection, OnOnePieceItIsTheGalerkinStepWrittenOutWithDenseMatrices) {
  const Region r = make_region({7, 6, 5});
  LinearFem fem(r.mesh, r.materials, r.fixed, FemSettings{});
  fem.set_displacements_mm(smooth_field(r));
  // Two nodes held where the field put them (a probe's contact): the step leaves them there.
  const int held[] = {r.grid.node_index(3, 2, 0), r.grid.node_index(4, 2, 0)};
  for (int n : held) fem.prescribe_displacement(n, fem.displacement_mm(n));
  const Eigen::VectorXd u0 = fem.displacements_mm();

  // The reference: P trilinear over the box's 8 corners, D the free DOFs.
  const int dofs = 3 * r.mesh.node_count();
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(dofs, 24);
  const Eigen::Vector3d extent = (r.grid.nodes - Eigen::Vector3i::Ones()).cast<double>();
  for (int k = 0; k < r.grid.nodes.z(); ++k) {
    for (int j = 0; j < r.grid.nodes.y(); ++j) {
      for (int i = 0; i < r.grid.nodes.x(); ++i) {
        const int n = r.grid.node_index(i, j, k);
        if (fem.holds_node(n)) continue;
        const Eigen::Vector3d t = Eigen::Vector3d(i, j, k).cwiseQuotient(extent);
        for (int c = 0; c < 8; ++c) {
          double w = 1.0;
          for (int a = 0; a < 3; ++a) w *= (c >> a) & 1 ? t[a] : 1.0 - t[a];
          for (int d = 0; d < 3; ++d) p(3 * n + d, 3 * c + d) = w;
        }
      }
    }
  }
  const Eigen::MatrixXd k = Eigen::MatrixXd(fem.stiffness());
  const Eigen::MatrixXd kc = p.transpose() * k * p;
  const Eigen::VectorXd expected = u0 + p * kc.ldlt().solve(p.transpose() * (-k * u0));

  const std::vector<SubVolumeBox> boxes{SubVolumeBox{.nodes = r.grid.nodes}};
  // Built before the probe holds anything: only the fixed nodes are fixed for it.
  LinearFem fresh(r.mesh, r.materials, r.fixed, FemSettings{});
  const std::vector<const DeformationEngine*> fresh_engines{&fresh};
  CoarseCorrection coarse(r.grid, boxes, fresh_engines);
  EXPECT_EQ(coarse.coarse_node_count(), 8);
  coarse.update(0, fem);
  ASSERT_TRUE(coarse.solve());
  coarse.apply(0, fem);
  EXPECT_LT((fem.displacements_mm() - expected).lpNorm<Eigen::Infinity>(), 1e-9);
  for (int n : held) {
    EXPECT_EQ(fem.displacement_mm(n), u0.segment<3>(3 * n));
  }
  // The step is the best in its space: a second one from where it left has nothing to do.
  coarse.update(0, fem);
  ASSERT_TRUE(coarse.solve());
  EXPECT_LT(coarse.largest_move_mm(0), 1e-9);
}

TEST(CoarseCorrection, TheMsdsForcesAreTheRestStiffnessTimesASmallMove) {
  const Region r = make_region({5, 4, 4});
  MsdsEngine msds(MsdsIntegrator::kImplicitEuler, r.mesh, r.materials, r.fixed, MsdsSettings{});
  const Eigen::VectorXd u = 1e-4 * smooth_field(r);
  msds.set_displacements_mm(u);
  Eigen::VectorXd forces(u.size());
  msds.tissue_forces_mn(forces);
  const Eigen::VectorXd linear = -(msds.rest_stiffness_mn_per_mm() * u);
  // The springs' nonlinearity is second order in the move.
  EXPECT_LT((forces - linear).norm(), 1e-3 * linear.norm());
  // A correction moves the free nodes only, and keeps the velocities.
  Eigen::VectorXd du = Eigen::VectorXd::Constant(u.size(), 0.01);
  msds.displace_free_nodes_mm(du);
  for (int n = 0; n < r.mesh.node_count(); ++n) {
    const Eigen::Vector3d moved = msds.displacements_mm().segment<3>(3 * n) - u.segment<3>(3 * n);
    EXPECT_NEAR(moved.norm(), r.fixed[n] ? 0.0 : std::sqrt(3.0) * 0.01, 1e-12);
  }
}

// Relaxation from a smooth field with no probe: the seams alone pass it on one seam a frame.
// Measured on this 3 × 3 split: 0.77 / 0.71 / 0.58 of the field left after 10 frames with the
// seams alone (PCG, explicit, implicit MSDS), 0.20 / 0.14 / 0.10 with the correction.
TEST(CoarseCorrection, AStitchedRegionRelaxesSeveralTimesFasterWithIt) {
  const Region r = make_region({32, 32, 6});
  hal::InlineJobSystem jobs;
  for (const EngineKind method : {EngineKind::kPcgFem, EngineKind::kCorotationalFem,
                                  EngineKind::kMsdsExplicit, EngineKind::kMsdsImplicit}) {
    double left[2] = {0.0, 0.0};
    for (const bool coarse : {false, true}) {
      StitchingSettings stitching{.sub_volumes = {3, 3, 1}, .selective = false};
      stitching.coarse_correction = coarse;
      StitchedVolume stitched(r.grid, r.materials, r.fixed, method, {}, stitching, &jobs);
      stitched.set_displacements_mm(smooth_field(r));
      const double start = max_norm(stitched.displacements_mm());
      for (int f = 0; f < 10; ++f) stitched.step(nullptr, 1.0 / 60);
      left[coarse] = max_norm(stitched.displacements_mm()) / start;
      if (coarse) {
        EXPECT_GT(stitched.last_stitch_stats().sub_volumes_corrected, 0);
      }
    }
    EXPECT_LT(left[1], 0.3 * left[0])
        << engine_key(method) << ": " << left[0] << " of the field left after 10 frames with the "
        << "seams alone, " << left[1] << " with the coarse correction";
  }
}

// Under a still probe the corrected region settles where one piece does.
TEST(CoarseCorrection, AStitchedPcgFemUnderAStillProbeSettlesWhereOnePieceDoes) {
  const Region r = make_region({22, 10, 8});
  hal::InlineJobSystem jobs;
  StitchingSettings stitching{.sub_volumes = {2, 1, 1}, .selective = false};
  stitching.coarse_correction = true;
  const EngineSettings engines = testing::stick_contact();
  StitchedVolume stitched(r.grid, r.materials, r.fixed, EngineKind::kPcgFem, engines, stitching,
                          &jobs);
  LinearFem one_piece(r.mesh, r.materials, r.fixed, engines.fem);
  const ProbeCollider probe =
      ProbeCollider::sphere(SphereCollider{Eigen::Vector3d(17.0, 9.0, 2.0 - 8.0), 8.0});
  for (int f = 0; f < 300; ++f) {
    stitched.step(&probe, 1.0 / 60);
    one_piece.step(&probe, 1.0 / 60);
  }
  one_piece.solve_to_tolerance(1e-10, 4000);
  const double peak = max_norm(one_piece.displacements_mm());
  ASSERT_GT(peak, 1.5);
  const double error = max_norm(stitched.displacements_mm() - one_piece.displacements_mm());
  EXPECT_LT(error, 0.02 * peak) << "error " << error << " mm of " << peak;
}

}  // namespace
}  // namespace ultrasim::sim
