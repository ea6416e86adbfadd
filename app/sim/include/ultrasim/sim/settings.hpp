#pragma once

#include <string>
#include <vector>

namespace ultrasim::sim {

// Linear elastic, isotropic material of one tissue class.
struct Material {
  int label = 0;                     // label value in the case's label volume
  std::string name;                  // "skin", "fat", ...
  double youngs_modulus_kpa = 10.0;  // E; tissue spans ~1 kPa (fat, empty vein) to ~1 MPa (tendon)
  double poisson_ratio = 0.45;       // nu in [0, 0.5); near 0.5 is near-incompressible
};

// Quasi-static linear FEM solved by preconditioned conjugate gradients.
struct FemSettings {
  // PCG iterations per frame, warm-started from the previous frame's displacement. The published
  // system used 20. More iterations: closer to the exact answer, linearly more time.
  int pcg_iterations_per_frame = 20;
  // Stop early when the residual norm falls below this fraction of the right-hand side norm.
  double relative_tolerance = 1e-8;
};

// The published probe collider: a sphere whose lowest point is the centre of the transducer face;
// mesh nodes inside it are pushed out to its surface.
struct SphereColliderSettings {
  double radius_mm = 30.0;  // larger: flatter, more probe-like contact; smaller: a fingertip
};

}  // namespace ultrasim::sim
