#include "ultrasim/kiosk/session.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

namespace ultrasim::kiosk {

namespace {

BscanControls controls_from(const config::AppSettings& settings, const imaging::ProbeGeometry& p) {
  BscanControls c;
  c.gain_db = settings.bscan.gain_db;
  c.tgc_db = settings.bscan.tgc_db;
  c.dynamic_range_db = settings.bscan.dynamic_range_db;
  c.depth_mm = p.depth_mm;
  return c;
}

imaging::BscanSettings display_settings(imaging::BscanSettings s, const BscanControls& c) {
  s.gain_db = c.gain_db;
  s.tgc_db = c.tgc_db;
  s.dynamic_range_db = c.dynamic_range_db;
  return s;
}

void check_range(const char* name, double value, double lo, double hi) {
  if (!(value >= lo && value <= hi)) {
    throw std::invalid_argument(std::string("B-scan control ") + name + " = " +
                                std::to_string(value) + " is outside [" + std::to_string(lo) +
                                ", " + std::to_string(hi) + "]");
  }
}

// The nodes of the mesh's skin face (its shallowest layer, z minimum: the case format puts the
// skin there), which the probe can touch.
std::vector<std::uint8_t> skin_face_nodes(const TissueCase& tissue) {
  const auto& p = tissue.mesh.rest_positions_mm;
  double top = p.empty() ? 0.0 : p[0].z();
  for (const auto& q : p) top = std::min(top, q.z());
  std::vector<std::uint8_t> skin(p.size(), 0);
  for (std::size_t n = 0; n < p.size(); ++n) {
    skin[n] = !tissue.fixed_nodes[n] && p[n].z() <= top + 1e-9 * (1.0 + std::abs(top));
  }
  return skin;
}

// Seconds from `last_us` to `now_us`, within [min_s, max_s] (`first_s` before any), and `now_us`
// becomes `last_us`: a step over the time since the last one, never a giant one after a stall.
double seconds_since(hal::TimestampUs& last_us, hal::TimestampUs now_us, double first_s,
                     double min_s, double max_s) {
  const double seconds =
      last_us < 0 ? first_s
                  : std::clamp(static_cast<double>(now_us - last_us) * 1e-6, min_s, max_s);
  last_us = now_us;
  return seconds;
}

}  // namespace

Session::Session(const TissueCase& tissue, const config::AppSettings& settings,
                 const hal::Clock& clock, hal::JobSystem& jobs)
    : tissue_(tissue),
      settings_(settings),
      clock_(clock),
      jobs_(jobs),
      engine_settings_{settings.fem, settings.exact, settings.msds, settings.corotational,
                       settings.hyperelastic},
      skin_nodes_(skin_face_nodes(tissue)),
      locator_(tissue.mesh),
      controls_(controls_from(settings, tissue.settings.probe)),
      probe_(tissue.settings.probe),
      grid_(probe_, settings.bscan.width_px, settings.bscan.height_px),
      acquisition_grid_(grid_),
      display_mapping_(grid_, display_settings(settings.bscan, controls_)),
      bscan_(static_cast<std::size_t>(settings.bscan.width_px) * settings.bscan.height_px,
             static_cast<std::uint8_t>(settings.bscan.background_grey)),
      node_positions_(3 * tissue.view_nodes.size(), 0.0f),
      node_displacement_(tissue.view_nodes.size(), 0.0f),
      structures_(tissue.structures),
      skin_(tissue) {
  probe_status_.reserve(160);
  surface_views_.reserve(tissue.structures.size() + 1);
  for (std::size_t i = 0; i < tissue.line_levels.size(); ++i) {
    line_levels_.push_back({tissue.line_levels[i], tissue.line_level_spacing_mm[i]});
  }
  switch_method(settings.sim.method);
  rebuild_image_pipeline();
  update_view();  // the tissue at rest: what the 3D view draws until its stage first runs
}

namespace {

bool split_into_sub_volumes(const TissueCase& tissue) {
  const auto& parts = tissue.settings.mesh.sub_volumes;
  return parts[0] * parts[1] * parts[2] > 1;
}

}  // namespace

bool method_runs_on(const TissueCase& tissue, sim::EngineKind method) {
  return !split_into_sub_volumes(tissue) || sim::stitchable(method);
}

std::unique_ptr<sim::DeformationEngine> Session::make_method(sim::EngineKind method) const {
  const config::CaseMesh& mesh = tissue_.settings.mesh;
  if (!method_runs_on(tissue_, method)) {
    throw std::invalid_argument(
        std::string(sim::engine_key(method)) + " cannot run on case '" + tissue_.settings.name +
        "': it is split into sub-volumes ([mesh] sub_volumes), and only "
        "pcg, corotational, msds-explicit and msds-implicit run stitched ([sim] method, or "
        "--method)");
  }
  if (split_into_sub_volumes(tissue_)) {
    sim::StitchingSettings stitching = settings_.stitching;
    stitching.sub_volumes = mesh.sub_volumes;
    stitching.overlap_nodes = mesh.overlap_nodes;
    return std::make_unique<sim::StitchedVolume>(tissue_.grid, tissue_.tet_materials,
                                                 tissue_.fixed_nodes, method, engine_settings_,
                                                 stitching, &jobs_);
  }
  return sim::make_engine(method, tissue_.mesh, tissue_.tet_materials, tissue_.fixed_nodes,
                          engine_settings_, skin_nodes_, &jobs_);
}

void Session::switch_method(sim::EngineKind method) {
  auto& slot = engines_[static_cast<std::size_t>(method)];
  if (!slot) slot = make_method(method);
  if (engine_ != nullptr && engine_ != slot.get()) {
    slot->set_displacements_mm(engine_->displacements_mm());
  }
  engine_ = slot.get();
  stitched_ = dynamic_cast<sim::StitchedVolume*>(engine_);
  refused_press_.reset();         // another method may take the press
  sim_budget_.forget_measures();  // another method's pieces and tail are not these
}

std::optional<sim::ProbeCollider> Session::probe_collider(
    const std::optional<hal::PoseSample>& pose) const {
  if (!pose) return std::nullopt;
  const auto& c = settings_.collider;
  const Eigen::Vector3d beam = pose->orientation * Eigen::Vector3d::UnitZ();
  if (c.shape == sim::ProbeContactShape::kSphere) {
    return sim::ProbeCollider::sphere(
        sim::SphereCollider::behind_face(pose->position_mm, beam, c.radius_mm), beam);
  }
  if (probe_.kind == imaging::ProbeKind::kConvex) {
    return sim::ProbeCollider::convex_face(pose->position_mm, pose->orientation, probe_.radius_mm,
                                           c.face_thickness_mm, c.edge_radius_mm);
  }
  return sim::ProbeCollider::linear_face(pose->position_mm, pose->orientation, probe_.width_mm,
                                         c.face_thickness_mm, c.edge_radius_mm);
}

void Session::rebuild_image_pipeline() {
  grid_ = imaging::BscanGrid(probe_, settings_.bscan.width_px, settings_.bscan.height_px);
  if (settings_.bscan.scan_lines > 0) {
    acquisition_grid_ = imaging::BscanGrid::scan_lines(probe_, settings_.bscan.scan_lines,
                                                       settings_.bscan.samples_per_line);
    scan_converter_.emplace(acquisition_grid_, grid_,
                            static_cast<std::uint8_t>(settings_.bscan.background_grey));
  } else {
    acquisition_grid_ = grid_;
    scan_converter_.reset();
  }
  fast_slicer_.reset();
  published_slicer_.reset();
  if (!scan_converter_ && settings_.bscan.slicer == imaging::SlicerMethod::kFast) {
    fast_slicer_.emplace(tissue_.mesh, grid_);
  } else if (!scan_converter_ && settings_.bscan.slicer == imaging::SlicerMethod::kPublished) {
    published_slicer_.emplace(tissue_.mesh, grid_);
  }
  acquired_.assign(
      static_cast<std::size_t>(acquisition_grid_.width_px()) * acquisition_grid_.height_px(),
      static_cast<std::uint8_t>(settings_.bscan.background_grey));
  display_mapping_ =
      imaging::DisplayMapping(acquisition_grid_, display_settings(settings_.bscan, controls_));
}

void Session::set_controls(const BscanControls& c) {
  check_range("gain_db", c.gain_db, -40.0, 40.0);
  for (double t : c.tgc_db) check_range("tgc_db", t, -30.0, 30.0);
  check_range("dynamic_range_db", c.dynamic_range_db, 10.0, 100.0);
  check_range("depth_mm", c.depth_mm, 10.0, 300.0);
  check_range("compression_mm", c.compression_mm, 0.0, 20.0);
  controls_ = c;
  probe_.depth_mm = c.depth_mm;
  rebuild_image_pipeline();
}

FrameOutcome Session::update(const std::optional<hal::PoseSample>& sample) {
  const FrameOutcome outcome = simulate(sample);
  update_bscan();
  update_view();
  return outcome;
}

FrameOutcome Session::simulate(const std::optional<hal::PoseSample>& sample,
                               hal::TimestampUs deadline_us) {
  FrameOutcome outcome;
  if (sample && sample->health == hal::PoseHealth::kOk && hal::is_valid(*sample)) {
    tracked_pose_ = sample;
  } else {
    outcome.pose_rejected = true;
  }
  if (tracked_pose_) {
    pose_ = tracked_pose_;
    pose_->position_mm +=
        controls_.compression_mm * (pose_->orientation * Eigen::Vector3d::UnitZ());
  }

  const hal::TimestampUs t0 = clock_.now_us();
  // Dynamic methods integrate over the time since the last frame (a 60 Hz frame at first, and
  // never more than 0.1 s: a stalled frame must not become one giant step).
  const double frame_dt_s = seconds_since(last_update_us_, t0, 1.0 / 60.0, 1e-4, 0.1);
  // While the method refuses the probe's pose, the tissue is pressed where it last took the
  // probe (RefusedPress).
  std::optional<hal::PoseSample> pressing = pose_;
  if (pose_) {
    pressing = refused_press_.pose_for(*pose_);
    outcome.probe_held = refused_press_.holding();
  } else {
    refused_press_.reset();
  }
  const std::optional<sim::ProbeCollider> collider = probe_collider(pressing);
  const sim::ProbeCollider* probe = collider ? &*collider : nullptr;
  // The method's work that can wait (CG iterations, contact rounds, sub-volumes the probe does
  // not touch) goes on only while a piece as long as the last still ends by the deadline, less
  // what the method went on doing after its last frame's first "no" (sched::PieceBudget). A
  // stitched method shares the time left over its seam exchanges and their batches, and keeps
  // its batches' tails back, itself (step_sharing).
  sim_budget_.start(t0, deadline_us,
                    stitched_ == nullptr ? sched::PieceBudget::Memory::kTailAndPiece
                                         : sched::PieceBudget::Memory::kNothing);
  // One pointer: small enough for std::function's local buffer, so no allocation per frame.
  const auto time_left = [this] { return sim_budget_.may_start_another(); };
  const sim::StepBudget budget = deadline_us < 0 ? sim::StepBudget{} : sim::StepBudget{time_left};
  if (stitched_ != nullptr) {
    // The touched sub-volumes' batches share the time out (StitchedVolume::step_sharing).
    const auto time_left_us = [this] { return sim_budget_.time_left_us(); };
    outcome.sim = stitched_->step_sharing(probe, frame_dt_s, budget, time_left_us);
    outcome.stitch = stitched_->last_stitch_stats();
  } else {
    outcome.sim = engine_->step_within(probe, frame_dt_s, budget);
  }
  if (deadline_us >= 0) sim_budget_.finish();
  if (pose_) refused_press_.record(verdict_of(outcome.sim));
  // Contact means tissue nodes are held by the probe: only then does a scanner show an image.
  // A probe pressed where the method refused it is in contact whatever the tissue's held pose
  // touches (backed off, it may touch nothing while the trainee presses on: the image then
  // showed "no contact" on ~40 % of the large soak's frames).
  in_contact_ = outcome.sim.contact_nodes > 0 || outcome.probe_held;
  outcome.in_contact = in_contact_;
  return outcome;
}

void Session::update_bscan() {
  if (controls_.frozen) {
    // The image holds still, as a frozen scanner's does; the tissue keeps following the probe.
  } else if (in_contact_) {
    imaging::ProbePose probe;
    probe.face_center_mm = pose_->position_mm;
    probe.axes = pose_->orientation.toRotationMatrix();
    if (fast_slicer_ || published_slicer_) {
      slice_in_parallel(probe);
    } else {
      locator_.rebuild(engine_->deformed_positions_mm());
      auto& target = scan_converter_ ? acquired_ : bscan_;
      imaging::slice_deformed_reference(tissue_.volume, tissue_.mesh, locator_, probe,
                                        acquisition_grid_, settings_.bscan, target);
      display_mapping_.apply(target);
      if (scan_converter_) scan_converter_->apply(acquired_, bscan_);
    }
    image_shows_tissue_ = true;
  } else {
    image_shows_tissue_ = false;
    std::fill(bscan_.begin(), bscan_.end(),
              static_cast<std::uint8_t>(settings_.bscan.background_grey));
  }
}

void Session::update_view() {
  const auto deformed = engine_->deformed_positions_mm();
  // Only the surface's nodes: the wireframe draws nothing else (the large case's 12,000: 0.07 ms
  // on one thread).
  constexpr int kChunkNodes = 2048;
  const int view_nodes = static_cast<int>(tissue_.view_nodes.size());
  hal::parallel_for(jobs_, (view_nodes + kChunkNodes - 1) / kChunkNodes, [&](int chunk) {
    const int end = std::min(view_nodes, (chunk + 1) * kChunkNodes);
    for (int v = chunk * kChunkNodes; v < end; ++v) {
      const std::uint32_t n = tissue_.view_nodes[v];
      for (int a = 0; a < 3; ++a) node_positions_[3 * v + a] = static_cast<float>(deformed[n][a]);
      node_displacement_[v] =
          static_cast<float>((deformed[n] - tissue_.mesh.rest_positions_mm[n]).norm());
    }
  });
  structures_.update(deformed, jobs_);
  // The skin over the tissue and around it, struck by the probe (it is the view's: it moves
  // when the view is refreshed, by the time since it last moved: a frame's at least, at most
  // 0.1 s, so frames the scheduler skipped the view in do not slow its springing back).
  const double frame_s = static_cast<double>(settings_.frame.budget_us) * 1e-6;
  const double skin_dt_s =
      seconds_since(last_view_us_, clock_.now_us(), frame_s, frame_s, std::max(frame_s, 0.1));
  const std::optional<sim::ProbeCollider> collider = probe_collider(pose_);
  skin_.step(deformed, collider ? &*collider : nullptr, skin_dt_s);
  surface_views_.assign(structures_.views().begin(), structures_.views().end());
  surface_views_.push_back(skin_.view());
}

void Session::slice_in_parallel(const imaging::ProbePose& probe) {
  const auto deformed = engine_->deformed_positions_mm();
  if (fast_slicer_) {
    const int parts = std::min(2 * jobs_.thread_count(), imaging::FastSlicer::kMaxParts);
    fast_slicer_->begin_prepare(tissue_.volume, deformed, probe, parts);
    hal::parallel_for(jobs_, parts, [&](int part) { fast_slicer_->classify_nodes(part); });
    hal::parallel_for(jobs_, parts, [&](int part) { fast_slicer_->find_cuts(part); });
    fast_slicer_->end_prepare();
  } else {
    published_slicer_->prepare(tissue_.volume, deformed, probe);
  }
  // Bands of rows from a shared counter: rows below the tissue cost little, so small bands
  // keep both threads busy. Each band is sliced and then mapped while it is in cache.
  constexpr int kBandRows = 16;
  const int rows = grid_.height_px();
  const int bands = (rows + kBandRows - 1) / kBandRows;
  hal::parallel_for(jobs_, bands, [&](int band) {
    const int begin = band * kBandRows, end = std::min(rows, begin + kBandRows);
    if (fast_slicer_) {
      fast_slicer_->slice_rows(settings_.bscan, begin, end, bscan_);
    } else {
      published_slicer_->slice_rows(settings_.bscan, begin, end, bscan_);
    }
    display_mapping_.apply_rows(bscan_, begin, end);
  });
}

render::FrameInput Session::frame_input(std::int64_t frame_index) const {
  render::FrameInput frame;
  frame.frame_index = frame_index;
  const imaging::ImageExtent extent = grid_.extent();
  frame.bscan.pixels = bscan_;
  frame.bscan.width_px = grid_.width_px();
  frame.bscan.height_px = grid_.height_px();
  frame.bscan.width_mm = static_cast<float>(extent.width_mm());
  frame.bscan.depth_mm = static_cast<float>(extent.depth_mm());
  frame.bscan.in_contact = image_shows_tissue_;
  frame.bscan.frozen = controls_.frozen;
  frame.bscan.gain_db = static_cast<float>(controls_.gain_db);
  frame.probe_status = probe_status_;

  frame.mesh.node_positions_mm = node_positions_;
  frame.mesh.line_indices = tissue_.line_levels.front();  // the finest
  frame.mesh.line_levels = line_levels_;
  frame.mesh.node_displacement_mm = node_displacement_;
  frame.surfaces = surface_views_;

  // A convex face is the chord of its arc, not the sector's width at depth.
  const double face_width_mm =
      probe_.kind == imaging::ProbeKind::kLinear
          ? probe_.width_mm
          : 2.0 * probe_.radius_mm * std::sin(probe_.fan_angle_deg * std::numbers::pi / 360.0);
  frame.probe.face_width_mm = static_cast<float>(face_width_mm);
  frame.probe.image_depth_mm = static_cast<float>(probe_.depth_mm);
  if (pose_) {
    Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
    m.topLeftCorner<3, 3>() = pose_->orientation.toRotationMatrix().cast<float>();
    m.topRightCorner<3, 1>() = pose_->position_mm.cast<float>();
    std::copy(m.data(), m.data() + 16, frame.probe.probe_to_patient.begin());  // column-major
    // The published sphere is drawn; a face collider is the probe model itself.
    if (settings_.collider.shape == sim::ProbeContactShape::kSphere) {
      const Eigen::Vector3d beam = pose_->orientation * Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d centre = pose_->position_mm - settings_.collider.radius_mm * beam;
      for (int a = 0; a < 3; ++a) {
        frame.probe.collider_center_mm[a] = static_cast<float>(centre[a]);
      }
      frame.probe.collider_radius_mm = static_cast<float>(settings_.collider.radius_mm);
    }
  }
  const Eigen::Vector3d lo = tissue_.volume.world_min_mm(), hi = tissue_.volume.world_max_mm();
  for (int a = 0; a < 3; ++a) {
    frame.scene_min_mm[a] = static_cast<float>(lo[a]);
    frame.scene_max_mm[a] = static_cast<float>(hi[a]);
  }
  return frame;
}

}  // namespace ultrasim::kiosk

namespace ultrasim::kiosk {

std::vector<render::PngText> Session::image_record() const {
  const auto number = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3f", v);
    return std::string(text);
  };
  std::vector<render::PngText> record = {
      {"Software", "ultrasim"},
      {"Case", tissue_.settings.name},
      {"Method", std::string(sim::engine_key(method()))},
      {"Gain dB", number(controls_.gain_db)},
      {"Depth mm", number(controls_.depth_mm)},
      {"Dynamic range dB", number(controls_.dynamic_range_db)},
      {"Frozen", controls_.frozen ? "yes" : "no"},
      {"Compression mm", number(controls_.compression_mm)},
  };
  std::string tgc;
  for (double t : controls_.tgc_db) tgc += (tgc.empty() ? "" : " ") + number(t);
  record.push_back({"TGC dB", tgc});
  if (pose_) {
    const auto& p = pose_->position_mm;
    const auto& q = pose_->orientation;
    record.push_back(
        {"Probe position mm", number(p.x()) + " " + number(p.y()) + " " + number(p.z())});
    record.push_back({"Probe orientation wxyz", number(q.w()) + " " + number(q.x()) + " " +
                                                    number(q.y()) + " " + number(q.z())});
  } else {
    record.push_back({"Probe position mm", "none"});
  }
  return record;
}

}  // namespace ultrasim::kiosk
