#include "ultrasim/config/app_settings.hpp"

#include <cstdint>

#include "array_codecs.hpp"
#include "document_schema.hpp"
#include "scalar_codecs.hpp"
#include "toml_document.hpp"

namespace ultrasim::config {
namespace {

TableSchema<render::DisplaySettings> display_schema() {
  using S = render::DisplaySettings;
  TableSchema<S> t;
  t.add(field("backend", &S::backend,
              Choice<render::DisplayBackend>{{{"offscreen", render::DisplayBackend::kOffscreen},
                                              {"kms", render::DisplayBackend::kKms}}},
              "Where frames go: offscreen = surfaceless EGL into an FBO (tests, headless runs); "
              "kms = the dedicated display through DRM/KMS page flips (no desktop)."));
  t.add(field("width_px", &S::width_px, IntegerIn<int>{64, 7680},
              "Offscreen display width in pixels (a KMS display takes its mode's)."));
  t.add(field("height_px", &S::height_px, IntegerIn<int>{64, 4320},
              "Offscreen display height in pixels."));
  t.add(field("kms_device", &S::kms_device, Text{true}, "kms: the DRM device."));
  t.add(field("kms_connector", &S::kms_connector, Text{},
              "kms: the output as the kernel names it (HDMI-A-1, DP-2, ...); empty: the first "
              "connected one."));
  t.add(field("kms_mode_width_px", &S::kms_mode_width_px, IntegerIn<int>{0, 16384},
              "kms: the mode's width; 0 (with height 0): the display's preferred mode."));
  t.add(field("kms_mode_height_px", &S::kms_mode_height_px, IntegerIn<int>{0, 16384},
              "kms: the mode's height."));
  t.add(field("kms_refresh_hz", &S::kms_refresh_hz, IntegerIn<int>{0, 1000},
              "kms: the mode's refresh rate; 0: the fastest at that size."));
  t.add(field("kms_legacy", &S::kms_legacy, Boolean{},
              "kms: legacy modeset and page flips even where atomic commits work."));
  t.add(field("pointer_device", &S::pointer_device, Text{},
              "The trainer's touch screen or mouse for the on-screen controls, an evdev node "
              "(/dev/input/eventN); empty: none."));
  return t;
}

TableSchema<imaging::BscanSettings> bscan_schema() {
  using S = imaging::BscanSettings;
  TableSchema<S> t;
  t.add(field("slicer", &S::slicer,
              Choice<imaging::SlicerMethod>{{{"fast", imaging::SlicerMethod::kFast},
                                             {"published", imaging::SlicerMethod::kPublished},
                                             {"reference", imaging::SlicerMethod::kReference}}},
              "How the B-scan is sampled from the deformed tissue (same image, different cost): "
              "fast = plane cuts of the mesh, published = the dissertation's row subdivision, "
              "reference = per-pixel point location."));
  t.add(field("width_px", &S::width_px, IntegerIn<int>{16, 4096},
              "B-scan image width in pixels; slicing time grows with width x height."));
  t.add(field("height_px", &S::height_px, IntegerIn<int>{16, 4096},
              "B-scan image height in pixels (spans the imaging depth)."));
  t.add(field("gain_db", &S::gain_db, RealIn::closed(-40.0, 40.0),
              "Gain in dB added to every pixel's echo level before display."));
  t.add(field("tgc_db", &S::tgc_db,
              FixedArray<RealIn, imaging::kTgcSliders>{RealIn::closed(-30.0, 30.0)},
              "Time-gain compensation in dB: 8 sliders from the probe face to the imaging "
              "depth, interpolated linearly."));
  t.add(field("dynamic_range_db", &S::dynamic_range_db, RealIn::closed(10.0, 100.0),
              "Echo range in dB shown from black to white; the case data spans 60 dB."));
  t.add(field("background_grey", &S::background_grey, IntegerIn<int>{0, 255},
              "Grey level shown outside the volume or the mesh."));
  t.add(field("scan_lines", &S::scan_lines, IntegerIn<int>{0, 1024},
              "Scan lines to acquire, then scan-convert to the display (a scanner's way); 0 "
              "slices the display grid directly."));
  t.add(field("samples_per_line", &S::samples_per_line, IntegerIn<int>{16, 4096},
              "Samples along each scan line, when scan_lines > 0."));
  return t;
}

// The PCG FEM's, the corotational FEM's and the MSDS's probe contact: the same keys in [fem],
// [corotational] and [msds].
template <typename S>
void add_held_contact_fields(TableSchema<S>& t) {
  using H = sim::HeldContactSettings;
  t.add(field("contact", &S::contact, &H::model,
              Choice<sim::HeldContactModel>{{{"coulomb-slip", sim::HeldContactModel::kCoulombSlip},
                                             {"stick", sim::HeldContactModel::kStick}}},
              "coulomb-slip = a held node slides along the probe where its tissue pulls it "
              "harder than friction_coefficient x its push; stick = the published collider, "
              "held in all three axes (a sliding probe drags the skin along)."));
  t.add(field("friction_coefficient", &S::contact, &H::friction_coefficient,
              RealIn::closed(0.0, 2.0),
              "Coulomb friction of the probe on the skin (coulomb-slip); 0: frictionless, as "
              "the exact FEM; gel-lubricated skin 0.02-0.2, but a face pressed deeper than its "
              "rounded edge then bulldozes the skin ahead of it."));
}

TableSchema<sim::FemSettings> fem_schema() {
  using S = sim::FemSettings;
  TableSchema<S> t;
  t.add(field("pcg_iterations_per_frame", &S::pcg_iterations_per_frame, IntegerIn<int>{1, 10'000},
              "PCG iterations per frame, warm-started; more: closer to exact, linearly more time "
              "(the published system used 20)."));
  t.add(field("relative_tolerance", &S::relative_tolerance, RealIn::open(0.0, 1.0),
              "Stop early when the residual norm falls below this fraction of the right-hand "
              "side norm."));
  t.add(field("max_inverted_fraction", &S::max_inverted_fraction, RealIn::closed(0.0, 1.0),
              "Above this fraction of inverted tets a frame is rejected and the last good "
              "shape kept."));
  add_held_contact_fields(t);
  return t;
}

TableSchema<sim::ProbeColliderSettings> collider_schema() {
  using S = sim::ProbeColliderSettings;
  TableSchema<S> t;
  t.add(field("shape", &S::shape,
              Choice<sim::ProbeContactShape>{{{"face", sim::ProbeContactShape::kFace},
                                              {"sphere", sim::ProbeContactShape::kSphere}}},
              "face = the transducer face (rounded box for a linear probe, cylinder section for "
              "a convex one); sphere = the published collider, its lowest point at the face."));
  t.add(field("radius_mm", &S::radius_mm, RealIn::open_closed(0.5, 500.0),
              "Sphere radius in mm; larger: flatter, more probe-like contact; smaller: a "
              "fingertip."));
  t.add(field("face_thickness_mm", &S::face_thickness_mm, RealIn::closed(2.0, 50.0),
              "Face extent across the scan plane (elevation), mm; its width comes from the "
              "case's probe."));
  t.add(field("edge_radius_mm", &S::edge_radius_mm, RealIn::closed(0.0, 10.0),
              "Rounding of the face's edges, mm (below half the face thickness)."));
  return t;
}

TableSchema<sim::SimSettings> sim_schema() {
  using S = sim::SimSettings;
  TableSchema<S> t;
  t.add(field("method", &S::method,
              Choice<sim::EngineKind>{{{"exact", sim::EngineKind::kExactFem},
                                       {"pcg", sim::EngineKind::kPcgFem},
                                       {"corotational", sim::EngineKind::kCorotationalFem},
                                       {"msds-explicit", sim::EngineKind::kMsdsExplicit},
                                       {"msds-implicit", sim::EngineKind::kMsdsImplicit},
                                       {"hyperelastic", sim::EngineKind::kHyperelasticFem}}},
              "Deformation method: exact = linear FEM solved exactly; pcg = the published "
              "linear FEM (fixed PCG budget); corotational = FEM with per-tet rotations; "
              "msds-explicit = the published mass-spring system; msds-implicit = the same, "
              "implicit Euler; hyperelastic = large-strain FEM, the reference (seconds a "
              "frame)."));
  return t;
}

TableSchema<sim::ExactFemSettings> exact_schema() {
  using S = sim::ExactFemSettings;
  TableSchema<S> t;
  t.add(field("contact", &S::contact,
              Choice<sim::ContactModel>{{{"frictionless", sim::ContactModel::kFrictionless},
                                         {"stick", sim::ContactModel::kStick}}},
              "frictionless = the probe pushes along its normal and never pulls (gel); stick = "
              "touched nodes held where the collider puts them (the published rule)."));
  t.add(field("max_contact_rounds", &S::max_contact_rounds, IntegerIn<int>{1, 100},
              "Active-set rounds per frame for frictionless contact."));
  t.add(field("max_cached_nodes", &S::max_cached_nodes, IntegerIn<int>{0, 100'000},
              "Off-skin nodes whose K^-1 columns are kept between frames."));
  t.add(field("max_inverted_fraction", &S::max_inverted_fraction, RealIn::closed(0.0, 1.0),
              "Above this fraction of inverted tets a frame is rejected and the last good "
              "shape kept."));
  return t;
}

TableSchema<sim::MsdsSettings> msds_schema() {
  using S = sim::MsdsSettings;
  TableSchema<S> t;
  t.add(field("stiffness_per_modulus_mm", &S::stiffness_per_modulus_mm,
              RealIn::open_closed(0.0, 1'000.0),
              "Spring stiffness k = E x this (kPa x mm = mN/mm); the published 0.002 E (Pa, "
              "N/m) is 2 mm."));
  t.add(field("damping_per_stiffness_s", &S::damping_per_stiffness_s, RealIn::closed(0.0, 10.0),
              "Spring damping c = k x this, seconds (published 0.1)."));
  t.add(field("density_kg_per_m3", &S::density_kg_per_m3, RealIn::open_closed(0.0, 20'000.0),
              "Tissue density for the lumped nodal masses (soft tissue ~1000)."));
  t.add(field("time_step_s", &S::time_step_s, RealIn::open_closed(0.0, 1.0),
              "Integration step, seconds (published 0.002-0.01)."));
  t.add(field("steps_per_frame", &S::steps_per_frame, IntegerIn<int>{1, 10'000},
              "Integration steps per frame (published 20-40); steps x dt is the simulated time "
              "per frame."));
  t.add(field("scale_mass_for_explicit_step", &S::scale_mass_for_explicit_step, Boolean{},
              "Explicit Euler: raise node masses just enough for time_step_s to be stable (with "
              "physical masses the limit is ~1e-7 s); statics unchanged, motion slower."));
  t.add(field("implicit_steps_per_frame", &S::implicit_steps_per_frame, IntegerIn<int>{1, 10'000},
              "Implicit Euler covers the frame's simulated time in this many steps."));
  t.add(field("max_inverted_fraction", &S::max_inverted_fraction, RealIn::closed(0.0, 1.0),
              "More inverted tets than this fraction of all fail a step (substep, then keep the "
              "last good shape)."));
  add_held_contact_fields(t);
  return t;
}

TableSchema<sim::CorotationalSettings> corotational_schema() {
  using S = sim::CorotationalSettings;
  TableSchema<S> t;
  t.add(field("pcg_iterations_per_frame", &S::pcg_iterations_per_frame, IntegerIn<int>{1, 10'000},
              "PCG iterations per frame on the rotated stiffness, warm-started."));
  t.add(field("relative_tolerance", &S::relative_tolerance, RealIn::open(0.0, 1.0),
              "Stop early when the residual norm falls below this fraction of the right-hand "
              "side norm."));
  t.add(field("max_inverted_fraction", &S::max_inverted_fraction, RealIn::closed(0.0, 1.0),
              "Above this fraction of inverted tets a frame is cut short along its update (a "
              "few folded under the probe's rim are accepted)."));
  t.add(field("rotation_update_tolerance", &S::rotation_update_tolerance, RealIn::closed(0.0, 1.0),
              "A tet keeps its rotation while its deformation gradient has turned less than "
              "this from it, radians (its forces then turned by less); 0 (with "
              "max_rotation_updates_fraction 1): every tet's rotation every frame."));
  t.add(field("max_rotation_updates_fraction", &S::max_rotation_updates_fraction,
              RealIn::open_closed(0.0, 1.0),
              "At most this fraction of the tets take a new rotation a frame, the most turned "
              "first (the others a frame or more later); 1: every tet turned past the tolerance."));
  add_held_contact_fields(t);
  return t;
}

TableSchema<sim::HyperelasticSettings> hyperelastic_schema() {
  using S = sim::HyperelasticSettings;
  TableSchema<S> t;
  t.add(field("newton_iterations_per_frame", &S::newton_iterations_per_frame,
              IntegerIn<int>{1, 10'000},
              "Newton iterations per solve (each contact round and the last), warm-started."));
  t.add(field("relative_force_tolerance", &S::relative_force_tolerance, RealIn::open(0.0, 1.0),
              "Converged when every free node's out-of-balance force is below this fraction of "
              "the largest held or contact force."));
  t.add(field("step_tolerance_mm", &S::step_tolerance_mm, RealIn::open(0.0, 1.0),
              "... or when a full Newton step moves no node further than this, mm."));
  t.add(field("max_contact_rounds", &S::max_contact_rounds, IntegerIn<int>{1, 100},
              "Augmented-Lagrangian rounds per frame for the probe's contact."));
  t.add(field("contact_tolerance_mm", &S::contact_tolerance_mm, RealIn::open(0.0, 1.0),
              "The rounds stop when no node is further inside the probe than this, mm."));
  return t;
}

TableSchema<sched::FrameBudgetSettings> frame_schema() {
  using S = sched::FrameBudgetSettings;
  TableSchema<S> t;
  t.add(field("budget_us", &S::budget_us, IntegerIn<std::int64_t>{1'000, 1'000'000},
              "Time budget of one frame in microseconds (16667: one frame at 60 Hz)."));
  t.add(field("simulation_budget_us", &S::simulation_budget_us,
              IntegerIn<std::int64_t>{1, 1'000'000},
              "Contact and deformation, us; runs every frame (an overrun is counted)."));
  t.add(field("bscan_budget_us", &S::bscan_budget_us, IntegerIn<std::int64_t>{1, 1'000'000},
              "B-scan, us; skipped (the last image held) when the frame has not this much left."));
  t.add(field("view_budget_us", &S::view_budget_us, IntegerIn<std::int64_t>{1, 1'000'000},
              "Mesh and vessel surfaces of the 3D view, us; skipped like the B-scan."));
  t.add(field("render_budget_us", &S::render_budget_us, IntegerIn<std::int64_t>{1, 1'000'000},
              "Drawing the screen, us; runs every frame, its time kept free of the skippable "
              "tasks."));
  return t;
}

TableSchema<sim::StitchingSettings> stitching_schema() {
  using S = sim::StitchingSettings;
  TableSchema<S> t;
  t.add(field("spring_stiffness_per_modulus_mm", &S::spring_stiffness_per_modulus_mm,
              RealIn::open_closed(0.0, 10'000.0),
              "Zero-length seam spring k = E of the stiffest tet at the node x this (mN/mm); "
              "stiffer: a smaller gap between the copies of a shared node."));
  t.add(field("split_overlap_stiffness", &S::split_overlap_stiffness, Boolean{},
              "Give each copy of a shared tet 1/copies of its stiffness, so the tied copies are "
              "as stiff as the tissue (false: each at full stiffness, as published)."));
  t.add(field("selective", &S::selective, Boolean{},
              "Step only the sub-volumes the probe may touch, their neighbours and a few more "
              "(published); false: every sub-volume every frame."));
  t.add(field("extra_sub_volumes_per_frame", &S::extra_sub_volumes_per_frame,
              IntegerIn<int>{0, 4096},
              "Selective: sub-volumes beyond the touched and their neighbours, hardest pulled by "
              "their seams first (published: 1)."));
  t.add(field("exchanges_per_frame", &S::exchanges_per_frame, IntegerIn<int>{1, 64},
              "PCG FEM: seam exchanges per frame, each sub-volume's frame in this many parts, "
              "anchors refreshed between them (2: the seams narrower than with 1 in the same "
              "time)."));
  t.add(field("explicit_msds_exchanges_per_frame", &S::explicit_msds_exchanges_per_frame,
              IntegerIn<int>{1, 64},
              "Explicit MSDS: seam exchanges per frame; must divide [msds] steps_per_frame (1: 2 "
              "made the large case's seams no narrower)."));
  t.add(field("implicit_msds_exchanges_per_frame", &S::implicit_msds_exchanges_per_frame,
              IntegerIn<int>{1, 64},
              "Implicit MSDS: seam exchanges per frame, one implicit step each at least; must "
              "divide [msds] steps_per_frame (2: nearer one piece than 1; a frame without the "
              "time for both runs one)."));
  t.add(field("implicit_msds_spring_stiffness_per_modulus_mm",
              &S::implicit_msds_spring_stiffness_per_modulus_mm, RealIn::open_closed(0.0, 10'000.0),
              "Implicit MSDS: its seam springs' k = E of the stiffest tet at the node x this "
              "(mN/mm), in place of spring_stiffness_per_modulus_mm (40: with the lead, the "
              "large case's press seams half as wide as at 20, its forces as near one piece)."));
  t.add(field("implicit_msds_seam_lead", &S::implicit_msds_seam_lead, RealIn::closed(0.0, 1.0),
              "Implicit MSDS: a copy whose twin steps later in the same exchange is anchored "
              "ahead of the twin by this fraction of the seam's move in one exchange of the last "
              "frame (0: at the twin's place, as published)."));
  t.add(field("corotational_exchanges_per_frame", &S::corotational_exchanges_per_frame,
              IntegerIn<int>{1, 64},
              "Corotational FEM: seam exchanges per frame (1: each part extracts rotations and "
              "assembles again, and 2 took twice the time)."));
  t.add(field("corotational_turn_check_interval_frames",
              &S::corotational_turn_check_interval_frames, IntegerIn<int>{1, 100},
              "Corotational FEM: a sub-volume checks a tet found within [corotational] "
              "rotation_update_tolerance once in this many updates of its warped system (one "
              "turned past it at every update); 1: every tet at every update, as one piece "
              "does."));
  t.add(field("corotational_rotation_update_interval_frames",
              &S::corotational_rotation_update_interval_frames, IntegerIn<int>{1, 100},
              "Corotational FEM: a sub-volume checks turns, extracts rotations and sums its "
              "blocks again in one of this many seam exchanges (a frame of N exchanges takes N; "
              "face neighbours in turn) and solves the last system in between; 1: every step, "
              "as one piece does (and under the stick contact)."));
  t.add(field("corotational_update_turns_held", &S::corotational_update_turns_held,
              IntegerIn<int>{0, 100},
              "Corotational FEM: a sub-volume whose batch's share of the frame is no more than "
              "what a batch with an update took (a full or late frame) solves the last system "
              "instead of its due update, at most this many due updates in a row (the CG takes "
              "the time; one out of the probe's reach that must update waits for a frame with the "
              "time, 120 times at most); 0: never held (and under the stick contact)."));
  t.add(field("coarse_correction", &S::coarse_correction, Boolean{},
              "Once a frame, the smooth coarse-grid displacement that brings the whole region "
              "closest to balance, added to every sub-volume: faster relaxation, but presses end "
              "elsewhere than one piece under the stick contact (false: the seams alone, as "
              "published)."));
  t.add(field("fine_correction_iterations", &S::fine_correction_iterations, IntegerIn<int>{0, 1000},
              "Once a frame, at most this many conjugate-gradient iterations on the stepped "
              "sub-volumes as one piece, within the frame's time: the seams settle around a press "
              "in a few frames (0: the seams alone, as published)."));
  t.add(field("seam_load_rate", &S::seam_load_rate, RealIn::closed(0.0, 1.0),
              "Each copy of a shared node remembers the load its seam carries, this fraction of "
              "its springs' pull added a frame, and its anchor pulls by that much more: the copies "
              "close up under a steady press (0: the springs alone, as published; the gap is the "
              "seam's load over k)."));
  t.add(field("refuse_gap_mm", &S::refuse_gap_mm, RealIn::open_closed(0.0, 1e3),
              "A frame that opens a seam wider than this (mm, between copies of a shared node) is "
              "refused as torn; the tissue keeps its last good shape."));
  t.add(field("sleep_force_mn", &S::sleep_force_mn, RealIn::closed(0.0, 1e6),
              "A sub-volume out of reach sleeps when its seams pull less than this (mN) ..."));
  t.add(field("sleep_motion_mm", &S::sleep_motion_mm, RealIn::closed(0.0, 1e3),
              "... and its last step moved no node more than this (mm)."));
  return t;
}

TableSchema<hal::ProbeSourceSettings> probe_schema() {
  using S = hal::ProbeSourceSettings;
  using K = hal::ProbeSourceKind;
  TableSchema<S> t;
  t.add(field("source", &S::source,
              Choice<K>{{{"scripted", K::kScripted},
                         {"can", K::kCan},
                         {"can-replay", K::kCanReplay},
                         {"camera", K::kCamera},
                         {"camera-images", K::kCameraImages},
                         {"keyboard", K::kKeyboard}}},
              "Where the probe's pose comes from: scripted = the headless run's script; can = "
              "the IMU probe on a SocketCAN interface; can-replay = a candump -l log of it; "
              "camera = a camera watching the marker dodecahedron; camera-images = the same "
              "from a folder of frames; keyboard = keys and mouse (desktop development)."));
  t.add(field("motion_file", &S::motion_file, Text{},
              "scripted: a motion file (one keyframe a line: time_s x_mm y_mm z_mm rx_deg ry_deg "
              "rz_deg [marker]) played instead of the built-in script; empty: the built-in one."));
  t.add(field("can_interface", &S::can_interface, Text{true},
              "can: the SocketCAN interface (e.g. can0, vcan0)."));
  t.add(field("can_log", &S::can_log, Text{},
              "can-replay: the candump -l file (ultrasim-probe-bringup --write-demo makes one)."));
  t.add(field("replay_speed", &S::replay_speed, RealIn::closed(0.01, 100.0),
              "can-replay: playback speed, 1 = as recorded."));
  t.add(field("replay_loop", &S::replay_loop, Boolean{},
              "can-replay: start again at the end of the log."));
  t.add(field("imu_rate_hz", &S::imu_rate_hz, RealIn::closed(1.0, 2'000.0),
              "can, can-replay: orientation rate expected until the probe's status says "
              "otherwise; 3 periods without one make the pose stale."));
  t.add(field("pivot_mm", &S::pivot_mm, FixedArray<RealIn, 3>{RealIn::closed(-1e4, 1e4)},
              "can, can-replay: where the probe's face rests in patient space, mm (a 3-DOF IMU "
              "gives orientation only)."));
  t.add(field("compression_mm_per_n", &S::compression_mm_per_n, RealIn::closed(0.0, 100.0),
              "can, can-replay: how far the probe's compression input presses it in along its "
              "beam, mm per newton."));
  t.add(field("max_compression_mm", &S::max_compression_mm, RealIn::closed(0.0, 100.0),
              "can, can-replay: the deepest press the compression input gives, mm."));
  t.add(field("camera_device", &S::camera_device, Text{true},
              "camera: the V4L2 device; a missing one is reported and retried every second."));
  t.add(field("camera_images", &S::camera_images, Text{},
              "camera-images: a folder of frames (PNG, JPEG, PGM, BMP), played in name order."));
  t.add(field("camera_fps", &S::camera_fps, RealIn::closed(1.0, 1'000.0),
              "camera, camera-images: frames a second asked of the camera / played."));
  t.add(field("camera_width_px", &S::camera_width_px, IntegerIn<int>{16, 8192},
              "camera: image width asked of the camera."));
  t.add(field("camera_height_px", &S::camera_height_px, IntegerIn<int>{16, 8192},
              "camera: image height asked of the camera."));
  t.add(field("camera_intrinsics", &S::camera_intrinsics,
              FixedArray<RealIn, 4>{RealIn::closed(0.0, 1e5)},
              "camera, camera-images: fx, fy, cx, cy in pixels (OpenCV's calibration)."));
  t.add(field("camera_distortion", &S::camera_distortion,
              FixedArray<RealIn, 5>{RealIn::closed(-100.0, 100.0)},
              "camera, camera-images: k1, k2, p1, p2, k3 (OpenCV's calibration)."));
  t.add(field("camera_pose", &S::camera_pose, FixedArray<RealIn, 6>{RealIn::closed(-1e4, 1e4)},
              "camera, camera-images: the camera in patient space: x, y, z (mm), then a "
              "rotation vector in degrees (camera looks along its +z, image y down)."));
  t.add(field("probe_in_body", &S::probe_in_body, FixedArray<RealIn, 6>{RealIn::closed(-1e4, 1e4)},
              "camera, camera-images: the probe's frame (face centre, +z along the beam) in the "
              "dodecahedron's: x, y, z (mm), then a rotation vector in degrees."));
  t.add(field("dodecahedron_edge_mm", &S::dodecahedron_edge_mm, RealIn::closed(5.0, 500.0),
              "camera, camera-images: edge of the printed dodecahedron net, mm "
              "(ultrasim-marker-select --net --markers tag36h11)."));
  t.add(field("keyboard_start_mm", &S::keyboard_start_mm,
              FixedArray<RealIn, 3>{RealIn::closed(-1e4, 1e4)},
              "keyboard: where the probe starts in patient space, mm."));
  t.add(field("keyboard_speed_mm_per_s", &S::keyboard_speed_mm_per_s, RealIn::closed(1.0, 1'000.0),
              "keyboard: how fast a held key moves the probe."));
  t.add(field("keyboard_device", &S::keyboard_device, Text{},
              "keyboard: an evdev node (/dev/input/event*); empty: the terminal's keys."));
  return t;
}

const DocumentSchema<AppSettings>& app_schema() {
  // Built once, read-only afterwards: safe to share between threads.
  static const DocumentSchema<AppSettings> schema = [] {
    DocumentSchema<AppSettings> d({
        "ultrasim application settings.",
        "Generated by config::default_app_toml() (config_test checks this file against it).",
        "Every key is optional; each shows its default.",
    });
    d.table("display", &AppSettings::display, display_schema(), "The display and its size.");
    d.table("bscan", &AppSettings::bscan, bscan_schema(),
            "The B-scan image grid and display mapping.");
    d.table("sim", &AppSettings::sim, sim_schema(),
            "Tissue deformation: which method runs (switchable live in the kiosk).");
    d.table("fem", &AppSettings::fem, fem_schema(),
            "Quasi-static linear FEM, solved by preconditioned conjugate gradients (method pcg).");
    d.table("exact", &AppSettings::exact, exact_schema(),
            "Quasi-static linear FEM solved exactly (method exact).");
    d.table("corotational", &AppSettings::corotational, corotational_schema(),
            "Corotational linear FEM (method corotational).");
    d.table("hyperelastic", &AppSettings::hyperelastic, hyperelastic_schema(),
            "Large-strain hyperelastic FEM (method hyperelastic).");
    d.table("msds", &AppSettings::msds, msds_schema(),
            "Mass-spring-damper system (methods msds-explicit and msds-implicit).");
    d.table("stitching", &AppSettings::stitching, stitching_schema(),
            "Volume stitching, for cases split into sub-volumes ([mesh] sub_volumes).");
    d.table("collider", &AppSettings::collider, collider_schema(),
            "The probe as the tissue feels it.");
    d.table("frame", &AppSettings::frame, frame_schema(), "The fixed per-frame time budget.");
    d.table("probe", &AppSettings::probe, probe_schema(),
            "Where the probe's pose comes from, and that source's settings.");
    return d;
  }();
  return schema;
}

}  // namespace

AppSettings parse_app_settings(std::string_view toml_text, std::string_view source_name) {
  const toml::table root = parse_toml(toml_text, source_name);
  return app_schema().read(root,
                           ReadContext{.source_name = std::string(source_name), .base_dir = {}});
}

AppSettings load_app_settings(const std::filesystem::path& path) {
  return parse_app_settings(read_text_file(path), path.string());
}

std::string format_app_toml(const AppSettings& settings) {
  return app_schema().write(settings, WriteContext{});
}

std::string default_app_toml() {
  return format_app_toml(AppSettings{});
}

}  // namespace ultrasim::config
