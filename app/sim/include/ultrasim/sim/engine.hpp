#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
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

// What a frame's checks found (EngineStepStats::diverged); the recovery is what was done about it.
enum class DivergenceCause {
  kNone,
  kNonFinite,  // a NaN or infinite displacement or velocity
  kEnergy,     // kinetic energy past the whole spring lattice's ceiling (an integrator blowing up)
  kRunaway,    // one node faster than its own springs could move it (MsdsEngine)
  kInverted,   // more tets inverted than the method's max_inverted_fraction
  kSeamTorn,   // a stitched seam opened past StitchingSettings::refuse_gap_mm
};
inline constexpr int kDivergenceCauseCount = 6;

// How a recovery is named in reports and tables: "none", "substepped", "reset", "kept-last-good".
std::string_view recovery_key(Recovery recovery);
// Likewise: "none", "non-finite", "energy", "runaway", "inverted", "seam-torn".
std::string_view cause_key(DivergenceCause cause);
// The worse of two recoveries: a reset is worse than keeping the last good shape, which is worse
// than substepping, which is worse than none.
Recovery worse_recovery(Recovery a, Recovery b);

// What one frame's step did, for the stats overlay and the run report.
struct EngineStepStats {
  int iterations = 0;              // PCG iterations, integration steps, or contact rounds
  double relative_residual = 0.0;  // where the method has one (PCG), else 0
  int contact_nodes = 0;           // nodes the probe touches this frame
  double contact_force_n = 0.0;    // |total force the probe exerts on the tissue|, newtons
  int inverted_tets = 0;           // tets with non-positive deformed volume after the step
  bool diverged = false;           // a check failed this frame: `cause` says which
  DivergenceCause cause = DivergenceCause::kNone;  // what was detected (the first, if several)
  Recovery recovery = Recovery::kNone;
  // step_within()'s budget ran out before the frame's work was done: the shape shown is less
  // converged (CG stopped early, sub-volumes left for later, a refused frame not retried) or, for
  // the exact FEM, leaves nodes it has no Green's functions for unheld (see its step_within()).
  bool cut_short = false;
};

// Asked before each further piece of a frame's work that a method can leave for later frames;
// false: stop there. An empty function never stops a step. Called from one thread at a time
// while step_within() runs (the MSDS asks from its task team's lead, which may be a job-system
// worker), never after it returns.
using StepBudget = std::function<bool()>;

// A zero-length spring pulling one node toward a target point (volume stitching: the target is the
// node's twin in the overlapping sub-volume). The explicit MSDS damps it like the tissue's
// springs (c = k × its damping per stiffness, on the node's velocity); the others do not.
struct AnchorSpring {
  int node = 0;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  double stiffness_mn_per_mm = 0.0;
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

  // step() inside a time budget, for the kiosk's fixed frame: the trade is accuracy, never
  // latency. The method asks may_continue() before each piece of work it can leave for later and
  // reports cut_short when it stopped early. The PCG and corotational FEMs and the implicit MSDS
  // stop their conjugate-gradient iterations (always one at least; warm-started, they converge
  // over the next frames); the explicit MSDS stops stepping (a few steps at least: the
  // frame integrates less simulated time); the MSDS retries a rejected frame with smaller steps
  // only while there is time (else it keeps the frame's start); the exact FEM stops its
  // frictionless contact rounds (one at least; the next frame carries on from its set) and does
  // not hold nodes whose Green's functions it has not got (each costs a full solve, more than a
  // frame has); a stitched volume leaves the sub-volumes the probe does not touch for later.
  // Methods with no such work ignore the budget. An empty may_continue: exactly step(). Does not
  // allocate (nor does the budget, if it fits std::function's local buffer: capture one pointer).
  virtual EngineStepStats step_within(const ProbeCollider* probe, double frame_dt_s,
                                      const StepBudget& may_continue) {
    (void)may_continue;
    return step(probe, frame_dt_s);
  }

  // Node-major x,y,z displacements from rest, mm, and rest + displacement; valid until the next
  // step().
  virtual const Eigen::VectorXd& displacements_mm() const = 0;
  virtual std::span<const Eigen::Vector3d> deformed_positions_mm() const = 0;

  // Live switch: continue from another engine's displacement field, at rest (zero velocity).
  // Fixed nodes stay at zero whatever `u` says. `u` must have 3 × node count entries.
  virtual void set_displacements_mm(const Eigen::VectorXd& u_mm) = 0;

  // Whether set_anchor_springs() works on this method: the MSDS and the PCG and corotational FEMs
  // add the springs to their systems; the exact FEM's factor, fixed at construction, cannot take
  // them, nor does the hyperelastic solver yet.
  virtual bool supports_anchor_springs() const { return false; }
  // Replaces the anchor springs, acting from the next step() on (none: an empty span). Nodes
  // strictly increasing, inside the mesh; targets finite; stiffness finite and ≥ 0. Anchors on
  // fixed nodes have no effect. Allocates only when there are more anchors than ever before (or,
  // explicit MSDS with mass scaling, when a node's anchor stiffness changes: its mass is rescaled
  // for the step to stay stable). Throws std::invalid_argument for bad anchors and
  // std::logic_error where not supported.
  virtual void set_anchor_springs(std::span<const AnchorSpring> /*anchors*/) {
    throw std::logic_error(std::string(name()) + " cannot take anchor springs (volume stitching)");
  }

  // What a stitched volume's coarse correction (coarse_correction.hpp) needs of a method that
  // takes anchor springs; the others throw std::logic_error.
  //
  // The tissue's stiffness linearised about rest (3·nodes square, node-major x,y,z, mN/mm): the
  // FEM's K, the springs' Σ k n nᵀ. Fixed and held nodes included. Allocates.
  virtual Eigen::SparseMatrix<double, Eigen::RowMajor> rest_stiffness_mn_per_mm() const {
    throw std::logic_error(std::string(name()) + " has no coarse-correction interface");
  }
  // The stiffness the method's last step solved with, times v_mm (3 × node count, mN/mm × mm),
  // where that is not the rest stiffness: the corotational FEM's warped K_R, with the rotations
  // its tets hold (the rest stiffness points a large rotation's step elsewhere: a stitched
  // region's fine correction tore the large case's seams under 13 mm presses). False, and out_mn
  // untouched, where the rest stiffness is the method's own (the PCG FEM) or its chosen
  // linearisation (the MSDS); the same answer for the engine's life. Does not allocate; const,
  // so one engine per thread may call it in parallel.
  virtual bool tangent_stiffness_times(const Eigen::VectorXd& /*v_mm*/,
                                       Eigen::VectorXd& /*out_mn*/) const {
    return false;
  }
  // The tissue's own force on every node at the current shape, mN (−K u for the FEM; the springs'
  // pull for the MSDS), without anchors, damping or the probe. `forces_mn` must have 3 × node
  // count entries. Does not allocate; const, so one engine per thread may call it in parallel.
  virtual void tissue_forces_mn(Eigen::VectorXd& /*forces_mn*/) const {
    throw std::logic_error(std::string(name()) + " has no coarse-correction interface");
  }
  // Whether the node is fixed or held on the probe after the last step (it does not move under
  // displace_free_nodes_mm()).
  virtual bool holds_node(int /*node*/) const {
    throw std::logic_error(std::string(name()) + " has no coarse-correction interface");
  }
  // A node the probe holds along its normal only, free to slide in the tangent plane against
  // `friction_mn` (the PCG FEM's Coulomb slip, solved inside its CG): a correction moves it in
  // that plane and counts the friction in its balance. Null for any other node (free, fixed,
  // held in all three axes) and for methods that slide their nodes between steps. Valid until
  // the next step.
  struct SlidingHold {
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    Eigen::Vector3d friction_mn = Eigen::Vector3d::Zero();
  };
  virtual const SlidingHold* sliding_hold(int /*node*/) const { return nullptr; }
  // Moves a node the probe holds (holds_node() and not fixed) to `position_mm` (finite), where
  // the next step's contact test takes it up again; any other node is left where it is. A
  // stitched volume puts the copies of a seam node that the probe holds in several sub-volumes
  // in one place. Does not allocate.
  virtual void move_held_node_mm(int /*node*/, const Eigen::Vector3d& /*position_mm*/) {
    throw std::logic_error(std::string(name()) + " has no coarse-correction interface");
  }
  // Moves every node neither fixed nor held by `du_mm`, and each sliding one (sliding_hold()) by
  // its part in the tangent plane (3 × node count entries, finite), keeping
  // the contacts and, for the MSDS, the velocities: a correction between frames, not a new start.
  // Does not allocate.
  virtual void displace_free_nodes_mm(const Eigen::VectorXd& /*du_mm*/) {
    throw std::logic_error(std::string(name()) + " has no coarse-correction interface");
  }
};

// Checks anchors as set_anchor_springs() documents; throws std::invalid_argument naming the first
// bad one.
void check_anchor_springs(std::span<const AnchorSpring> anchors, int node_count);

}  // namespace ultrasim::sim
