#pragma once

#include <Eigen/Core>
#include <span>
#include <string_view>

#include "ultrasim/sim/probe_collider.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// What went wrong in a step and what the engine did about it. A step never leaves non-finite or
// inverted garbage in the displacements it reports.
enum class Recovery {
  kNone,
  kSubstepped,    // the frame was re-run with smaller steps
  kReset,         // the state was thrown away and the tissue returned to rest
  kKeptLastGood,  // the frame's answer was rejected; the last good shape is shown again
};

// What one frame's step did, for the stats overlay and the run report.
struct EngineStepStats {
  int iterations = 0;              // PCG iterations, integration steps, or contact rounds
  double relative_residual = 0.0;  // where the method has one (PCG), else 0
  int contact_nodes = 0;           // nodes the probe touches this frame
  double contact_force_n = 0.0;    // |total force the probe exerts on the tissue|, newtons
  int inverted_tets = 0;           // tets with non-positive deformed volume after the step
  bool diverged = false;           // NaN, energy growth or inversion was detected this frame
  Recovery recovery = Recovery::kNone;
};

// One deformation method on one tet mesh. Units: mm, kPa, mN, seconds. Nodes flagged fixed stay
// at rest. The frame thread owns it; step() does not allocate once warmed up (its largest
// contact set seen).
class DeformationEngine {
 public:
  virtual ~DeformationEngine() = default;

  virtual EngineKind kind() const = 0;
  virtual std::string_view name() const = 0;

  // Advances one frame: the probe where it is now (nullptr: lifted off the skin) and the frame's
  // duration (dynamic methods integrate over it; quasi-static ones ignore it).
  virtual EngineStepStats step(const ProbeCollider* probe, double frame_dt_s) = 0;

  // Node-major x,y,z displacements from rest, mm, and rest + displacement; valid until the next
  // step().
  virtual const Eigen::VectorXd& displacements_mm() const = 0;
  virtual std::span<const Eigen::Vector3d> deformed_positions_mm() const = 0;

  // Live switch: continue from another engine's displacement field, at rest (zero velocity).
  // Fixed nodes stay at zero whatever `u` says. `u` must have 3 × node count entries.
  virtual void set_displacements_mm(const Eigen::VectorXd& u_mm) = 0;
};

}  // namespace ultrasim::sim
