// A stitched frame does not allocate once warmed up: anchors are refreshed into buffers sized at
// construction, the schedule and the shown positions likewise (the simulation step's rule,
// DESIGN.md §3), for every method that can be stitched, selective or not.

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {
namespace {

TEST(StitchingAllocation, AStitchedFrameDoesNotAllocateOnceWarmedUp) {
  geometry::GridSpec grid;
  grid.nodes = {18, 10, 5};
  grid.spacing_mm = Eigen::Vector3d::Constant(2.0);
  const geometry::TetMesh mesh = geometry::make_grid_tet_mesh(grid);
  const std::vector<Material> materials(mesh.tets.size(), Material{1, "tissue", 30.0, 0.45});
  std::vector<std::uint8_t> fixed(mesh.rest_positions_mm.size(), 0);
  for (std::size_t n = 0; n < fixed.size(); ++n) fixed[n] = mesh.rest_positions_mm[n].z() == 8.0;
  hal::InlineJobSystem jobs;
  for (auto method : {EngineKind::kPcgFem, EngineKind::kCorotationalFem, EngineKind::kMsdsExplicit,
                      EngineKind::kMsdsImplicit}) {
    for (bool selective : {true, false}) {
      for (int correction : {0, 1, 2}) {  // none, coarse, fine
        StitchingSettings stitching;
        stitching.sub_volumes = {3, 2, 1};
        stitching.selective = selective;
        stitching.coarse_correction = correction == 1;
        stitching.fine_correction_iterations = correction == 2 ? 20 : 0;
        StitchedVolume stitched(grid, materials, fixed, method, EngineSettings{}, stitching, &jobs);
        // Warm up on the deepest press (the engines' largest contact sets), then press again.
        const auto probe_at = [](double depth_mm) {
          return ProbeCollider::sphere(SphereCollider{Eigen::Vector3d(17, 9, depth_mm - 6), 6});
        };
        for (int f = 0; f < 8; ++f) {
          const ProbeCollider p = probe_at(0.25 * f);
          stitched.step(&p, 1.0 / 60);
        }
        long allocations = 0;
        // Every other frame under a budget (the kiosk's: a lambda capturing one pointer) that
        // lets half the CG iterations through.
        int asked = 0;
        const StepBudget budget = [&asked] { return ++asked % 2 == 0; };
        for (int f = 0; f < 8; ++f) {
          const ProbeCollider p = probe_at(2.0 - 0.25 * f);
          ::ultrasim::testing::start_counting_allocations();
          if (f % 2 == 0) {
            stitched.step(&p, 1.0 / 60);
          } else {
            stitched.step_within(&p, 1.0 / 60, budget);
          }
          allocations += ::ultrasim::testing::stop_counting_allocations();
        }
        EXPECT_EQ(allocations, 0) << stitched.name() << (selective ? " selective" : " all")
                                  << ", correction " << correction;
      }
    }
  }
}

}  // namespace
}  // namespace ultrasim::sim
