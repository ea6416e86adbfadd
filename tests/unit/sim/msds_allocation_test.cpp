// MsdsEngine::step() does not allocate: every buffer is sized at construction (the simulation
// step's rule, DESIGN.md §3), with contacts, recovery and both integrators.

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "block_fixture.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {
namespace {

ProbeCollider press(double depth_mm) {
  return ProbeCollider::sphere(
      SphereCollider::behind_face({0, 0, depth_mm}, Eigen::Vector3d::UnitZ(), 15.0));
}

// Allocations made by `frames` frames of `engine` under a probe pressing ever deeper.
long allocations_in_frames(MsdsEngine& engine, int frames, double first_depth_mm) {
  long allocations = 0;
  for (int frame = 0; frame < frames; ++frame) {
    const ProbeCollider probe = press(first_depth_mm + 0.5 * frame);
    ::ultrasim::testing::start_counting_allocations();
    engine.step(&probe, 1.0 / 60);
    allocations += ::ultrasim::testing::stop_counting_allocations();
  }
  return allocations;
}

TEST(MsdsAllocation, StepDoesNotAllocateWithContactsRecoveryOrEitherIntegrator) {
  const auto b = testing::make_block({9, 5, 5}, [](const Eigen::Vector3d&) {
    return Material{1, "tissue", 30.0};
  });
  for (auto integrator : {MsdsIntegrator::kExplicitEuler, MsdsIntegrator::kImplicitEuler}) {
    // The published settings (mass-scaled explicit steps) and, for recovery, physical masses at
    // the published step: the explicit engine diverges, re-runs and resets.
    for (bool scaled : {true, false}) {
      MsdsSettings s;
      s.scale_mass_for_explicit_step = scaled;
      MsdsEngine engine(integrator, b.mesh, b.materials, b.fixed, s);
      EXPECT_EQ(allocations_in_frames(engine, 6, 0.5), 0) << engine.name() << " scaled " << scaled;
    }
  }
}

}  // namespace
}  // namespace ultrasim::sim
