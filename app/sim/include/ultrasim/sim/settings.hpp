#pragma once

#include <array>
#include <string>
#include <vector>

namespace ultrasim::sim {

// Linear elastic, isotropic material of one tissue class.
struct Material {
  int label = 0;                     // label value in the case's label volume
  std::string name;                  // "skin", "fat", ...
  double youngs_modulus_kpa = 10.0;  // E; tissue spans ~1 kPa (fat, empty vein) to ~1 MPa (tendon)
  double poisson_ratio = 0.45;       // nu in [0, 0.5); near 0.5 is near-incompressible
  // How fast the tissue stiffens as it is squeezed (γ of HyperelasticLaw, dimensionless, ≥ 0);
  // only the hyperelastic FEM uses it: 0 is neo-Hookean; linear methods have no large strain.
  double stiffening = 0.0;
};

// How a tet that the label volume cuts into several tissues gets its material.
enum class MaterialMixing {
  // The tissue at the tet's centroid, as published: a tet the vein's lumen half fills is all
  // muscle or all lumen, so on a grid coarser than the lumen its wall is as stiff as the muscle.
  kCentroid,
  // The Reuss (uniform-stress) average of the tissues in the tet by volume: as soft as its phases
  // in series. The lower bound on the mixture's stiffness; on the default case it converges to
  // the fine mesh's answer from the other side of the centroid rule, and closer (docs/accuracy.md).
  kReuss,
};

// How the PCG FEM's, the corotational FEM's and the MSDS's probe holds a node it catches (the
// exact FEM has its own ContactModel).
enum class HeldContactModel {
  // The published collider: a caught node is held at its push-out point in all three axes for the
  // step. A probe sliding along the skin drags the skin along and ploughs the tissue ahead of it
  // (docs/accuracy.md, "A sliding probe").
  kStick,
  // Coulomb friction: a held node whose tissue pulls it along the probe's surface harder than
  // friction_coefficient × its push slides along the surface; the rest stick. 0: frictionless, as
  // the exact FEM's contact. The PCG and corotational FEM solve the slide inside their CG (held
  // along the probe's normal only, against a friction force of that bound: a still probe's patch
  // settles with the tissue); the MSDS slides each node a step at a time to where its pull is
  // down to the bound.
  kCoulombSlip,
};

struct HeldContactSettings {
  HeldContactModel model = HeldContactModel::kCoulombSlip;
  // Frictionless by default, as the exact and hyperelastic FEM's contact (gel): a face pressed
  // deeper than its rounded edge meets the skin with its side, and friction there holds the
  // skin it pushes ahead, so the probe bulldozes it along a slide (μ 0.1: 29 mm, 0.7 -> 6.6 N
  // where the frictionless law keeps 0.76 N; docs/accuracy.md). Gel-lubricated skin measures
  // of the order of 0.02-0.2.
  double friction_coefficient = 0.0;
};

// Quasi-static linear FEM solved by preconditioned conjugate gradients.
struct FemSettings {
  // PCG iterations per frame, warm-started from the previous frame's displacement. The published
  // system used 20. More iterations: closer to the exact answer, linearly more time.
  int pcg_iterations_per_frame = 20;
  // Stop early when the residual norm falls below this fraction of the right-hand side norm.
  double relative_tolerance = 1e-8;
  // A linear model pressed hard inverts a few tets under the probe's rim long before its answer
  // is useless; a probe pushed through the tissue inverts many. Above this fraction of all tets
  // the frame is rejected and the last good shape kept.
  double max_inverted_fraction = 0.005;
  HeldContactSettings contact;
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
  // Integration step and steps per frame (published: 0.002-0.01 s, 20-40 steps). The simulated
  // time per frame is steps × dt, for both integrators.
  double time_step_s = 0.005;
  int steps_per_frame = 20;
  // Explicit Euler with physical masses is stable only below ~1e-7-1e-6 s on tissue meshes (the
  // stiffest spring over the lightest node); the published step is 10^4-10^5 times that. As
  // explicit FE codes do, raise each free node's mass just enough for time_step_s to be stable
  // (mass scaling): the static answer is unchanged, the motion slower. false: physical masses.
  bool scale_mass_for_explicit_step = true;
  // Implicit Euler is stable at any step: it covers the frame's simulated time in this many steps.
  int implicit_steps_per_frame = 2;
  // Implicit Euler under a budget: a step whose CG the budget stopped is the next step's CG start
  // where it lowers that step's energy (msds_implicit.cpp). A stitched volume's sub-volumes do
  // not: it costs a product a step, and the large case's stitched frames, planned on their
  // batches' cost, ran past 16.7 ms on 192-220 of 571 frames against 53-59.
  bool continue_stopped_steps = true;
  // As FemSettings::max_inverted_fraction: more inverted tets than this fraction fail a step.
  double max_inverted_fraction = 0.005;
  HeldContactSettings contact;
};

// Corotational linear FEM: per-tet rotation extracted by polar decomposition each frame, the
// linear stiffness applied in each tet's rotated frame; solved by PCG like the linear FEM.
struct CorotationalSettings {
  int pcg_iterations_per_frame = 20;  // warm-started, as the published linear FEM
  double relative_tolerance = 1e-8;
  // As FemSettings::max_inverted_fraction: a probe face's rounded rim folds a few tets long
  // before the answer is useless. Above this fraction of all tets (counting those with a free
  // node) a frame is cut short along its update; with 0, no frame may end with more inverted
  // tets than it started with.
  double max_inverted_fraction = 0.005;
  // A tet keeps the rotation it has while its deformation gradient has turned less than this
  // (radians, to first order) away from it: its polar decomposition and its share of the
  // assembly are skipped, its forces then turned by less than this. A tet that only stretched or
  // squeezed has not turned, and most of a mesh away from the probe barely moves from frame to
  // frame. 0 (with max_rotation_updates_fraction 1): every tet's rotation every frame. 1e-2
  // (0.6°): against every rotation exact, 0.4-0.8 % of the peak displacement under a held press,
  // 0.2-0.3 % under a slide (where the rotations' one-frame lag costs 1-6 %), and the stitched
  // large case's touched sub-volumes fit the simulation's share (1e-3: 6.5 ms a frame against
  // 4.3 ms; docs/accuracy.md, "Kept rotations", docs/benchmarks.md).
  double rotation_update_tolerance = 1e-2;
  // At most this fraction of the tets take a new rotation in a frame, the most turned first; the
  // others keep theirs (and turn further) until a later frame has room for them. A tet whose
  // rotation is lost (inverted, collapsed, or too sheared for the one it holds) takes a new one
  // at every update (every frame, or rotation_update_interval_frames'), outside the cap. Under a
  // deep press whose CG cannot catch up inside the frame's share, the shape creeps every frame and
  // 15 % of a stitched sub-volume's tets turned past the tolerance each frame: their rotations
  // and their blocks' sums took the time the CG needed (13 mm presses on the large case's seams:
  // a quarter fewer frames over 16.7 ms at 2 % than without a cap, every marker within 2 % of the
  // uncapped engine's; docs/benchmarks.md, docs/accuracy.md). 1: every tet past the tolerance.
  double max_rotation_updates_fraction = 0.02;
  // A tet found within rotation_update_tolerance is checked again once in this many updates of
  // the warped system (a tet past it, lost, or given a new rotation: at every update; every tet
  // after the shape is set from outside): once in this × rotation_update_interval_frames steps. 1
  // (one piece): every tet every frame. A stitched volume's sub-volumes take [stitching]
  // corotational_turn_check_interval_frames.
  int turn_check_interval_frames = 1;
  // The warped system (turns checked, rotations extracted, their blocks and rhs summed again) is
  // brought up to date in one step of this many, the rotation_update_phase-th (counted from
  // construction, or by CorotationalFem::set_update_clock()); the steps between solve the last
  // one (the first step after the shape is set from outside updates). 1 (one piece): every step.
  // A stitched volume's sub-volumes take [stitching]
  // corotational_rotation_update_interval_frames, face neighbours in alternate phases.
  int rotation_update_interval_frames = 1;
  int rotation_update_phase = 0;  // in [0, rotation_update_interval_frames)
  // At most this many due updates in a row are held by CorotationalFem::hold_next_update() (a
  // stitched batch whose share is short: the CG takes the time instead); the next due one updates
  // whatever the time. 0 (one piece): never held. A stitched volume's sub-volumes take [stitching]
  // corotational_update_turns_held.
  int max_update_turns_held = 0;
  // The CG's start needs K u: carried over from the last solve (its residual, and the columns
  // of the nodes moved since) and computed afresh once in this many solves, which bounds the
  // rounding the carried one gathers. 1: a product every solve and nothing carried (the
  // reference the carried one is tested against).
  int tissue_product_refresh_steps = 16;
  // An update whose moved tets are fewer than this fraction of all swaps their terms in K_R's
  // blocks tet by tet: each one's ten blocks above the diagonal lose the term of the rotation it
  // held before the extraction and take its new one after (twenty terms a tet, one thread).
  // More, and each block of the rows they hold is summed again from all its tets (ten terms a
  // tet of those rows, both threads). 0: always summed again (the reference the swaps are
  // tested and benchmarked against).
  double term_swap_max_fraction = 0.25;
  // As the PCG FEM's: Coulomb slip solved inside the CG, frictionless by default.
  HeldContactSettings contact;
};

// The deformation methods the kiosk can switch between live, on the same mesh.
enum class EngineKind {
  kPcgFem,           // (a) published quasi-static linear FEM, PCG with a fixed iteration budget
  kMsdsExplicit,     // (b) published mass-spring-damper system, explicit Euler
  kExactFem,         // (c) quasi-static linear FEM solved exactly (factor once, condense contact)
  kCorotationalFem,  // (d) corotational linear FEM (per-tet rotation by polar decomposition)
  kMsdsImplicit,     // (e) mass-spring-damper system, implicit Euler (stable at any step)
  kHyperelasticFem,  // (f) large-strain hyperelastic FEM, Newton's method (the vessel reference)
};

// Which deformation method runs.
struct SimSettings {
  EngineKind method = EngineKind::kExactFem;
};

// How the exact FEM's probe holds the nodes it touches.
enum class ContactModel {
  // Gel-lubricated skin: the probe pushes along its surface normal and never pulls; nodes slide
  // along the face. Solved exactly by an active set within the frame (Hertz's assumption).
  kFrictionless,
  // The published collider: a node inside the probe is held at its push-out point, all three
  // axes, as long as it stays inside (what the PCG FEM does; use it to compare the two).
  kStick,
};

// The exact quasi-static FEM (factor once, condense the probe's contact).
struct ExactFemSettings {
  ContactModel contact = ContactModel::kFrictionless;
  // Active-set rounds per frame for frictionless contact (release pulling nodes, add
  // penetrating ones). The set from the last frame is the start, so a moving probe needs 1-3.
  int max_contact_rounds = 8;
  // Nodes not among the contact candidates whose K⁻¹ columns (3 each, free-DOF length, double)
  // are kept between frames; one that comes into contact costs 3 solves with the factor. Nodes in
  // the current frame's set are never evicted, so the cache may exceed this meanwhile.
  int max_cached_nodes = 256;
  // As FemSettings::max_inverted_fraction.
  double max_inverted_fraction = 0.005;
};

// The hyperelastic FEM: Newton's method on the large-strain equilibrium, contacts by active set.
struct HyperelasticSettings {
  // Newton iterations per solve (each contact round and the final solve), warm-started from the
  // last frame; a solve stops early once converged. A lumen snapping shut under the probe takes
  // ~60; a probe moving a few tenths of a millimetre, 5-10.
  int newton_iterations_per_frame = 100;
  // Converged: the largest out-of-balance force at a free node is below this fraction of the
  // largest force at a held node (or of 1 mN with nothing held), and the last step moved no node
  // by more than step_tolerance_mm.
  double relative_force_tolerance = 1e-5;
  double step_tolerance_mm = 1e-6;
  // The probe's contact is frictionless (gel): each round solves with a penalty and moves each
  // node's contact force (an augmented Lagrangian multiplier) until no node is more than
  // contact_tolerance_mm inside the probe, or max_contact_rounds.
  int max_contact_rounds = 8;
  double contact_tolerance_mm = 1e-3;
};

// How a large region is split and stitched.
struct StitchingSettings {
  // Sub-volumes along x, y, z (published: 5 × 5 × 1; 1 × 1 × 1: one piece, no stitching).
  std::array<int, 3> sub_volumes{1, 1, 1};
  // Node layers neighbours share (published: 2; one shared layer would let the seam kink).
  int overlap_nodes = 2;
  // Zero-length spring between the copies of a shared node, per unit Young's modulus of the
  // stiffest tet at the node, mm (kPa × mm = mN/mm). Stiffer: a smaller gap between the copies
  // (the gap is the seam's force over this), and for the explicit MSDS heavier overlap nodes.
  double spring_stiffness_per_modulus_mm = 20.0;
  // The cells neighbours share are meshed in each of them: tied together, the copies are as stiff
  // as all of them in parallel, and the seam band is that many times too stiff (the published
  // split; ~8 % displacement error across a seam under the probe). true: each copy of a shared
  // tet gets 1 / copies of its Young's modulus, so the tied copies add up to the tissue's
  // stiffness. Masses are not split: the static answer does not depend on them.
  bool split_overlap_stiffness = true;
  // Selective simulation (published §5.2): each frame only the sub-volumes the probe may touch,
  // their neighbours and extra_sub_volumes_per_frame others, those pulled hardest by their seams
  // first. false: every sub-volume every frame.
  bool selective = true;
  int extra_sub_volumes_per_frame = 1;
  // Seam exchanges per frame of the PCG FEM: each sub-volume's frame is cut into this many parts
  // (its CG iterations shared among them) and the seams' anchors are refreshed between them, so
  // a disturbance crosses this many seams a frame (published: several iterations, then the
  // stitching forces). Two: on the large case's sweep-press (4 ms for the simulation, two
  // threads) the widest seam 0.09-0.12 mm against 0.13-0.16 with one and the forces within 0.5 N
  // of one piece's, in the same time (docs/accuracy.md).
  int exchanges_per_frame = 2;
  // The same for the explicit MSDS (its steps shared among the parts); must divide
  // MsdsSettings::steps_per_frame. One: with two the large case's sweep-press seams were 0.29-0.33
  // against 0.48 mm once (2026-11-28) and 0.52 against 0.36-0.40 on 2026-12-07, its forces
  // stronger (66-68 against 58-60 N): no steady gain.
  int explicit_msds_exchanges_per_frame = 1;
  // The same for the implicit MSDS (its implicit steps shared among the parts, one each at
  // least); must divide MsdsSettings::steps_per_frame. Two: the error against one piece 10
  // frames after a placed probe 13.3 % against 18.1 % with one (0.6 against 3.3 % after 60), and
  // a frame without the time for both runs one (StitchedVolume::step_sharing): the large case's
  // sweep-press ran its simulation at p90 4.15-4.17 ms against 5.0-5.2 with one (render-capped
  // frames over 16.7 ms 8 against 26-35 of 571; docs/benchmarks.md).
  int implicit_msds_exchanges_per_frame = 2;
  // The implicit MSDS's seam springs, per Young's modulus as spring_stiffness_per_modulus_mm
  // (the other methods'), and how far their anchors lead (implicit_msds_seam_lead). Under the
  // large case's 8 mm press the seams carry a load that changes faster than the remembered loads
  // follow, and stand apart by what they lag over k: 0.21-0.31 mm at 20 E, 168-200 of its 571
  // frames over 0.1 mm. 40 E with the lead: 0.13-0.23 mm, 8-45 frames, the sweep's forces as at
  // 20 E; 40 E alone held the tissue to copies a frame old (the sweep 18 N against 16, one piece
  // 12; docs/accuracy.md).
  double implicit_msds_spring_stiffness_per_modulus_mm = 40.0;
  // Implicit MSDS: a copy whose twin steps later in the same exchange is anchored where the
  // twin is expected to be once it has stepped: its place plus this fraction of the seam's move
  // (the copies' mean) in one exchange of the last frame in which every copy stepped, each axis
  // limited to what its last two frames' moves agree on (the smaller; none at a reversal or
  // after a frame that did not step every copy: a probe put down at once is no move to carry
  // on). Without it a stiff seam drags each copy back to where its twin was. The mean, not the
  // twin's own move: a seam whose copies swap sides would feed its own swing (a twin's move led
  // the corotational FEM's seams to tear). The quasi-static FEMs' copies go where their anchors
  // are, and a lead kept their seams moving under a sliding probe: the implicit MSDS's alone.
  // 0: anchored to the twin's place, as published.
  double implicit_msds_seam_lead = 0.7;
  // The same for the corotational FEM. One: each part extracts its tets' rotations and sums its
  // blocks again before its CG, so two parts doubled that work (large case, sweep-press, 1e-3
  // rad: simulation p50 11.1 against 6.5-6.9 ms; widest seam 0.067 against 0.078 mm).
  int corotational_exchanges_per_frame = 1;
  // A stitched corotational sub-volume checks a tet found within rotation_update_tolerance once
  // in this many of its warped system's updates (CorotationalSettings::
  // turn_check_interval_frames; with corotational_rotation_update_interval_frames 2, once in four
  // steps; a frame of
  // corotational_exchanges_per_frame parts takes that many; 1 under the stick contact, whose
  // answer is where the path caught the nodes: checked every other frame a stitched press
  // settled 8.1 % from one piece against 0.69 %). The check, every tet's
  // deformation gradient against its rotation, was the largest part of a touched sub-volume's
  // fixed work (0.48 of 1.7 ms a step under the large case's seam presses, its CG one iteration
  // a frame); at 2 that step took 1.47 ms and the presses' frames over 16.7 ms fell from 316 to
  // 179, the held forces within 2.4 %. One piece, whose CG has the time (the default case:
  // nothing gained), checks every frame: a tet found turned a frame late lags a sliding probe
  // further (docs/benchmarks.md, docs/accuracy.md).
  int corotational_turn_check_interval_frames = 2;
  // A stitched corotational sub-volume brings its warped system up to date in one of this many
  // of the volume's seam exchanges (CorotationalSettings::rotation_update_interval_frames; a
  // frame of corotational_exchanges_per_frame parts takes that many), face neighbours in turn,
  // and solves the last one in between; 1 under the stick contact, as the turn check. Under the
  // large case's seam presses the rotations' work was 0.8 of a touched step's 1.5 ms and the CG had
  // one iteration a frame: at 2 the frames over 16.7 ms (the rendering at its reserve) fell from
  // 255-351 to 66-103 of 1,315, and the time freed went to the CG, whose one iteration a frame
  // held the forces at 1.5 times those of the same run solved each frame (at 2 none moved away
  // from it, some nearer: 1.3-1.5 times). A CG with time to converge pays for the halved rotations
  // instead: twice the RMS error against every rotation exact, still under 1 % of the peak
  // (docs/benchmarks.md, docs/accuracy.md).
  int corotational_rotation_update_interval_frames = 2;
  // A stitched corotational sub-volume whose batch's share of the frame (the time left less what
  // is kept back for the batches after it and the work after the steps) is no more than what a
  // batch with an update took (a full frame, or a late one) solves the last warped system instead
  // of its due update, at most this many due updates in a row (the next one updates whatever the
  // time; CorotationalSettings::max_update_turns_held; one out of the probe's reach whose next
  // update cannot be held waits for a frame with the time for it, 120 times at most); 0 under the
  // stick contact, as the intervals.
  // The time goes to the CG, whose one iteration a frame is what held the forces above the solved
  // run's: under the large case's seam presses the held markers came from 1.57 to 1.17 times the
  // same run's solved each frame (1.21 at 1 turn held, 1.14 at 3), and the large soak's frames
  // over 16.7 ms from 293-419 to 63-195 of 9,058 (docs/benchmarks.md, docs/accuracy.md).
  // Nothing is held without a frame budget.
  int corotational_update_turns_held = 2;
  // Once a frame, a coarse correction (coarse_correction.hpp): the smooth displacement over a
  // coarse grid (a node at each overlap band's middle) that lowers the whole region's energy most,
  // added to every sub-volume, so a disturbance reaches across the region in one frame instead
  // of one seam a frame. Off by default: it relaxes a region 4-6 times faster, but under the
  // published stick contact it ends presses elsewhere than one piece (docs/accuracy.md). Costs
  // each stepped sub-volume one force evaluation, the frame a dense solve of 3 × coarse nodes
  // (216 for 5 × 5 × 1), and a move of every sub-volume it reaches (explicit MSDS, 25 × 15³:
  // +3 to +7 ms a frame, docs/benchmarks.md).
  bool coarse_correction = false;
  // Once a frame, after the sub-volumes' steps, at most this many conjugate-gradient iterations
  // on the stepped sub-volumes as one piece (fine_correction.hpp; none once the free nodes'
  // imbalance is under 1e-3 of the load, fewer when the frame's time is up): the seams settle
  // around a press in a few frames instead of tens (docs/accuracy.md: ≤ 2 % of one piece ten
  // frames after a placed probe for the PCG FEM and the implicit MSDS; not for the explicit MSDS,
  // whose stick contact then catches other rim nodes than one piece's). 0: off (the seams alone,
  // as published).
  int fine_correction_iterations = 0;
  // Each copy of a shared node remembers the load its seam carries, and its anchor pulls by that
  // much more (an augmented Lagrangian; the loads add up to zero over a node's copies, so they push
  // no node as a whole): after every accepted frame in which all of a node's copies stepped, this
  // fraction of the springs' pull on each copy (the mean of this frame's and the last's) is added
  // to its load (where they did not all step the loads fade, and a frame refused with nothing in
  // the probe's reach halves those of the seams it went back on). The springs then hold only what
  // the loads have not caught up with, and under a steady press the copies close up instead of
  // standing apart by the load over k (2 × 1 split, 4 mm press: the MSDS's seams 0.12-0.13 → 0.04
  // mm, the PCG FEM's 0.030 → 0.009 mm; docs/accuracy.md). Faster overshoots where the sub-volumes'
  // solves stop short (the implicit MSDS tore the large case's seams at 1.0); 0: the springs alone,
  // as published.
  double seam_load_rate = 0.25;
  // A frame that opens a seam wider than this (the largest distance between copies of a shared
  // node, mm) is refused as a whole, as one whose sub-volume refused its step: the seam has torn
  // (an explicit MSDS sub-volume pressed far past its depth folded while its neighbour did not;
  // the soak's large case accepted 10-27 mm), and the shown midpoints would blend two copies that
  // no longer follow each other. A seam already wider may close or hold (widen by 1e-3 mm at
  // most). Under the soaks' presses an intact seam opens 1.6 mm at most.
  double refuse_gap_mm = 3.0;
  // A sub-volume out of the probe's reach sleeps once its seams pull less than sleep_force_mn
  // and its last step moved no node more than sleep_motion_mm; a seam pulling harder wakes it.
  double sleep_force_mn = 0.05;
  double sleep_motion_mm = 1e-4;
};

// The probe as the tissue feels it.
enum class ProbeContactShape {
  kSphere,  // the published collider: a sphere whose lowest point is the transducer face's centre
  kFace,    // the transducer face: a rounded box (linear probe) or cylinder section (convex)
};

struct ProbeColliderSettings {
  ProbeContactShape shape = ProbeContactShape::kFace;
  double radius_mm = 30.0;  // sphere: larger, flatter contact; smaller, a fingertip
  // Face: its extent across the scan plane (elevation) and the rounding of its edges; its width
  // (and a convex face's radius) come from the case's probe.
  double face_thickness_mm = 10.0;
  double edge_radius_mm = 2.0;
};

}  // namespace ultrasim::sim
