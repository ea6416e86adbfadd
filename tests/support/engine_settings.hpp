#pragma once

// Engine settings the tests and benchmarks ask for again and again: the PCG FEM's and the MSDS's
// probe contact, and the PCG FEM's iteration budget.

#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::testing {

// `settings` with the PCG FEM's, the corotational FEM's and the MSDS's held contact
// (HeldContactSettings) set to `model` with `friction_coefficient`.
inline sim::EngineSettings with_held_contact(sim::HeldContactModel model,
                                             double friction_coefficient = 0.0,
                                             sim::EngineSettings settings = {}) {
  for (sim::HeldContactSettings* c :
       {&settings.fem.contact, &settings.corotational.contact, &settings.msds.contact}) {
    c->model = model;
    c->friction_coefficient = friction_coefficient;
  }
  return settings;
}

// The published stick contact for the PCG FEM, the corotational FEM and the MSDS. Most of the price
// of stitching against one piece under a still probe is measured and documented with it: the answer
// then depends only on which nodes the probe caught, and the same frames catch the same nodes
// stitched and in one piece. With friction any state whose held nodes' pull stays inside the
// friction cone is at rest, and the two reach different ones by their different paths
// (docs/accuracy.md); the default frictionless slip has one answer, and the PCG FEM's tests hold
// both contacts to it (StitchedVolume.PcgFemMatchesTheOnePieceSolutionAndTheSeamCloses,
// FineCorrection's ten frames).
inline sim::EngineSettings stick_contact() {
  return with_held_contact(sim::HeldContactModel::kStick);
}

// The PCG FEM with its own iteration budget and tolerance, the rest default.
inline sim::FemSettings pcg_settings(int iterations, double relative_tolerance) {
  sim::FemSettings s;
  s.pcg_iterations_per_frame = iterations;
  s.relative_tolerance = relative_tolerance;
  return s;
}

}  // namespace ultrasim::testing
