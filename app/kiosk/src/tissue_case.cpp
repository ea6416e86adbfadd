#include "ultrasim/kiosk/tissue_case.hpp"

#include <string>

#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/kiosk/tet_materials.hpp"

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
  c.grid = geometry::GridSpec::spanning(lo, hi, nodes);
  c.mesh = geometry::make_grid_tet_mesh(c.grid);

  c.tet_materials =
      tet_materials(c.mesh, c.labels, c.settings.materials, mesh_settings.material_mixing, toml);

  c.fixed_nodes.assign(c.mesh.rest_positions_mm.size(), 0);
  for (std::size_t n = 0; n < c.fixed_nodes.size(); ++n) {
    const Eigen::Vector3d& p = c.mesh.rest_positions_mm[n];
    for (auto face : mesh_settings.fixed_faces) c.fixed_nodes[n] |= on_face(p, lo, hi, face);
    const int label = c.labels.sample_nearest(p, 0);
    for (int fixed_label : mesh_settings.fix_label) c.fixed_nodes[n] |= label == fixed_label;
  }

  // The surface's nodes in mesh order, and each line's ends as indices among them.
  const auto surface_edges = geometry::unique_edges(geometry::boundary_faces(c.mesh));
  std::vector<std::int64_t> view_index(c.mesh.rest_positions_mm.size(), -1);
  for (const auto& edge : surface_edges) view_index[edge[0]] = view_index[edge[1]] = 0;
  for (std::size_t n = 0; n < view_index.size(); ++n) {
    if (view_index[n] < 0) continue;
    view_index[n] = static_cast<std::int64_t>(c.view_nodes.size());
    c.view_nodes.push_back(static_cast<std::uint32_t>(n));
  }
  const auto add_lines = [&](const auto& edges, std::vector<std::uint32_t>& lines) {
    for (const auto& edge : edges) {
      lines.push_back(static_cast<std::uint32_t>(view_index[edge[0]]));
      lines.push_back(static_cast<std::uint32_t>(view_index[edge[1]]));
    }
  };
  // The tets' face diagonals put the surface edges about half a cell apart.
  const double cell_mm = c.grid.spacing_mm.minCoeff();
  add_lines(surface_edges, c.line_levels.emplace_back());
  c.line_level_spacing_mm.push_back(static_cast<float>(0.5 * cell_mm));
  for (int stride = 1; stride < c.grid.nodes.maxCoeff(); stride *= 2) {
    add_lines(geometry::grid_surface_lines(c.grid, stride), c.line_levels.emplace_back());
    c.line_level_spacing_mm.push_back(static_cast<float>(stride * cell_mm));
  }
  c.structures = build_display_surfaces(c.labels, c.mesh);
  return c;
}

}  // namespace ultrasim::kiosk
