#include "ultrasim/kiosk/tissue_case.hpp"

#include <map>
#include <string>

#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::kiosk {

namespace {

Eigen::Vector3d to_vector(const std::array<double, 3>& a) {
  return {a[0], a[1], a[2]};
}

bool on_face(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
             config::BoxFace face) {
  const double tolerance = 1e-9 * (hi - lo).norm();
  switch (face) {
    case config::BoxFace::kXMin:
      return std::abs(p.x() - lo.x()) <= tolerance;
    case config::BoxFace::kXMax:
      return std::abs(p.x() - hi.x()) <= tolerance;
    case config::BoxFace::kYMin:
      return std::abs(p.y() - lo.y()) <= tolerance;
    case config::BoxFace::kYMax:
      return std::abs(p.y() - hi.y()) <= tolerance;
    case config::BoxFace::kZMin:
      return std::abs(p.z() - lo.z()) <= tolerance;
    case config::BoxFace::kZMax:
      return std::abs(p.z() - hi.z()) <= tolerance;
  }
  return false;
}

}  // namespace

TissueCase load_tissue_case(const std::filesystem::path& case_dir) {
  TissueCase c;
  c.settings = config::load_case_settings(case_dir);
  c.volume = imaging::read_volume_u8(c.settings.volume_path);
  c.labels = imaging::read_volume_u8(c.settings.labels_path);
  const std::string toml = (case_dir / "case.toml").string();
  if (c.labels.size() != c.volume.size() || !c.labels.origin_mm().isApprox(c.volume.origin_mm()) ||
      !c.labels.spacing_mm().isApprox(c.volume.spacing_mm())) {
    throw CaseError(c.settings.labels_path.string() +
                    ": label volume must share the echo volume's grid (size, spacing, origin)");
  }

  const auto& mesh_settings = c.settings.mesh;
  const Eigen::Vector3d lo = mesh_settings.region_min_mm ? to_vector(*mesh_settings.region_min_mm)
                                                         : c.volume.world_min_mm();
  const Eigen::Vector3d hi = mesh_settings.region_max_mm ? to_vector(*mesh_settings.region_max_mm)
                                                         : c.volume.world_max_mm();
  const Eigen::Vector3i nodes(mesh_settings.nodes[0], mesh_settings.nodes[1],
                              mesh_settings.nodes[2]);
  c.mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(lo, hi, nodes));

  std::map<int, const sim::Material*> by_label;
  for (const auto& m : c.settings.materials) by_label[m.label] = &m;
  std::map<int, int> unassigned;  // label → tets without a material
  c.tet_materials.reserve(c.mesh.tets.size());
  for (const auto& tet : c.mesh.tets) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (auto n : tet) centroid += c.mesh.rest_positions_mm[n] / 4.0;
    const int label = c.labels.sample_nearest(centroid, 0);
    const auto it = by_label.find(label);
    if (it == by_label.end()) {
      ++unassigned[label];
      c.tet_materials.push_back(sim::Material{});
    } else {
      c.tet_materials.push_back(*it->second);
    }
  }
  if (!unassigned.empty()) {
    const auto& [label, count] = *unassigned.begin();
    throw CaseError(toml + ": [[materials]]: no entry for label " + std::to_string(label) +
                    ", which fills " + std::to_string(count) + " tets of the mesh");
  }

  c.fixed_nodes.assign(c.mesh.rest_positions_mm.size(), 0);
  for (std::size_t n = 0; n < c.fixed_nodes.size(); ++n) {
    const Eigen::Vector3d& p = c.mesh.rest_positions_mm[n];
    for (auto face : mesh_settings.fixed_faces) c.fixed_nodes[n] |= on_face(p, lo, hi, face);
    const int label = c.labels.sample_nearest(p, 0);
    for (int fixed_label : mesh_settings.fix_label) c.fixed_nodes[n] |= label == fixed_label;
  }

  for (const auto& edge : geometry::unique_edges(geometry::boundary_faces(c.mesh))) {
    c.surface_lines.push_back(static_cast<std::uint32_t>(edge[0]));
    c.surface_lines.push_back(static_cast<std::uint32_t>(edge[1]));
  }
  c.structures = build_display_surfaces(c.labels, c.mesh);
  return c;
}

}  // namespace ultrasim::kiosk
