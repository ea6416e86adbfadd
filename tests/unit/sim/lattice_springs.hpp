#pragma once

// The springs the MSDS lattices' tests lay out (msds_kernels_test.cpp,
// msds_implicit_lattice_test.cpp): the engine's for a block, with an extra loose spring between
// two far nodes (its offset lies on no dense diagonal).

#include <vector>

#include "block_fixture.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim::testing {

inline std::vector<MsdsSpring> springs_with_a_loose_one(const Block& b) {
  // The springs do not depend on the integrator.
  const MsdsEngine engine(MsdsIntegrator::kImplicitEuler, b.mesh, b.materials, b.fixed,
                          MsdsSettings{});
  std::vector<MsdsSpring> springs(engine.springs().begin(), engine.springs().end());
  const int far = b.mesh.node_count() - 3;
  springs.push_back(
      {2, far, (b.mesh.rest_positions_mm[far] - b.mesh.rest_positions_mm[2]).norm(), 55.0, 5.5});
  return springs;
}

}  // namespace ultrasim::sim::testing
