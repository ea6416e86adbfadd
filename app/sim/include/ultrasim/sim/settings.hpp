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

// The published mass-spring-damper system (MSDS): every tet edge a spring, duplicates merged by
// summing stiffness and damping. Used by the explicit (published) and implicit Euler engines.
struct MsdsSettings {
  // Spring stiffness per unit Young's modulus of the tets sharing the edge, mm: k = E × this
  // (kPa × mm = mN/mm). The published k = 0.002·E (E in Pa, k in N/m) is 2 mm.
  double stiffness_per_modulus_mm = 2.0;
  // Damping per unit stiffness, seconds: c = k × this (published 0.1).
  double damping_per_stiffness_s = 0.1;
  // Tissue density for the lumped nodal masses, kg/m³ (soft tissue ≈ water).
  double density_kg_per_m3 = 1000.0;
  // Integration step and steps per frame (published: 0.002-0.01 s, 20-40 steps).
  double time_step_s = 0.005;
  int steps_per_frame = 20;
};

// Corotational linear FEM: per-tet rotation extracted by polar decomposition each frame, the
// linear stiffness applied in each tet's rotated frame; solved by PCG like the linear FEM.
struct CorotationalSettings {
  int pcg_iterations_per_frame = 20;  // warm-started, as the published linear FEM
  double relative_tolerance = 1e-8;
};

// The published probe collider: a sphere whose lowest point is the centre of the transducer face;
// mesh nodes inside it are pushed out to its surface.
struct SphereColliderSettings {
  double radius_mm = 30.0;  // larger: flatter, more probe-like contact; smaller: a fingertip
};

}  // namespace ultrasim::sim
