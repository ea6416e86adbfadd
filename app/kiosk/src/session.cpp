#include "ultrasim/kiosk/session.hpp"

#include <algorithm>

namespace ultrasim::kiosk {

Session::Session(const TissueCase& tissue, const config::AppSettings& settings,
                 const hal::Clock& clock)
    : tissue_(tissue),
      settings_(settings),
      clock_(clock),
      fem_(tissue.mesh, tissue.tet_materials, tissue.fixed_nodes, settings.fem),
      locator_(tissue.mesh),
      grid_(tissue.settings.probe, settings.bscan.width_px, settings.bscan.height_px),
      bscan_(static_cast<std::size_t>(settings.bscan.width_px) * settings.bscan.height_px,
             static_cast<std::uint8_t>(settings.bscan.background_grey)),
      node_positions_(3 * tissue.mesh.rest_positions_mm.size(), 0.0f),
      node_displacement_(tissue.mesh.rest_positions_mm.size(), 0.0f) {}

FrameOutcome Session::update(const std::optional<hal::PoseSample>& sample) {
  FrameOutcome outcome;
  if (sample && sample->health == hal::PoseHealth::kOk && hal::is_valid(*sample)) {
    pose_ = sample;
  } else {
    outcome.pose_rejected = true;
  }

  const hal::TimestampUs t0 = clock_.now_us();
  if (pose_) {
    const Eigen::Vector3d beam = pose_->orientation * Eigen::Vector3d::UnitZ();
    outcome.fem = fem_.step(
        sim::SphereCollider::behind_face(pose_->position_mm, beam, settings_.collider.radius_mm));
  } else {
    outcome.fem = fem_.step_without_contact();
  }
  // Contact means tissue nodes are held by the probe: only then does a scanner show an image.
  in_contact_ = outcome.fem.contact_nodes > 0;
  outcome.in_contact = in_contact_;
  const hal::TimestampUs t1 = clock_.now_us();

  const auto deformed = fem_.deformed_positions_mm();
  locator_.rebuild(deformed);
  if (in_contact_) {
    imaging::ProbePose probe;
    probe.face_center_mm = pose_->position_mm;
    probe.axes = pose_->orientation.toRotationMatrix();
    imaging::slice_deformed_reference(tissue_.volume, tissue_.mesh, locator_, probe, grid_,
                                      settings_.bscan, bscan_);
  } else {
    std::fill(bscan_.begin(), bscan_.end(),
              static_cast<std::uint8_t>(settings_.bscan.background_grey));
  }
  for (std::size_t n = 0; n < deformed.size(); ++n) {
    for (int a = 0; a < 3; ++a) node_positions_[3 * n + a] = static_cast<float>(deformed[n][a]);
    node_displacement_[n] =
        static_cast<float>((deformed[n] - tissue_.mesh.rest_positions_mm[n]).norm());
  }
  const hal::TimestampUs t2 = clock_.now_us();
  outcome.sim_us = t1 - t0;
  outcome.slice_us = t2 - t1;
  return outcome;
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
  frame.bscan.in_contact = in_contact_;

  frame.mesh.node_positions_mm = node_positions_;
  frame.mesh.line_indices = tissue_.surface_lines;
  frame.mesh.node_displacement_mm = node_displacement_;

  const auto& probe = tissue_.settings.probe;
  frame.probe.face_width_mm = static_cast<float>(extent.width_mm());
  frame.probe.image_depth_mm = static_cast<float>(probe.depth_mm);
  if (pose_) {
    Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
    m.topLeftCorner<3, 3>() = pose_->orientation.toRotationMatrix().cast<float>();
    m.topRightCorner<3, 1>() = pose_->position_mm.cast<float>();
    std::copy(m.data(), m.data() + 16, frame.probe.probe_to_patient.begin());  // column-major
    const Eigen::Vector3d beam = pose_->orientation * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d centre = pose_->position_mm - settings_.collider.radius_mm * beam;
    for (int a = 0; a < 3; ++a) frame.probe.collider_center_mm[a] = static_cast<float>(centre[a]);
    frame.probe.collider_radius_mm = static_cast<float>(settings_.collider.radius_mm);
  }
  const Eigen::Vector3d lo = tissue_.volume.world_min_mm(), hi = tissue_.volume.world_max_mm();
  for (int a = 0; a < 3; ++a) {
    frame.scene_min_mm[a] = static_cast<float>(lo[a]);
    frame.scene_max_mm[a] = static_cast<float>(hi[a]);
  }
  return frame;
}

}  // namespace ultrasim::kiosk
