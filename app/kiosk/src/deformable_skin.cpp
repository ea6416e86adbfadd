#include "ultrasim/kiosk/deformable_skin.hpp"

#include <algorithm>
#include <limits>

#include "ultrasim/kiosk/tissue_case.hpp"

namespace ultrasim::kiosk {

namespace {

// The tissue's extent in x and y and its top (the skin's depth).
struct Footprint {
  Eigen::Vector2d min{std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  Eigen::Vector2d max{std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
  double top_z = std::numeric_limits<double>::max();
};

Footprint footprint(const TissueCase& tissue) {
  Footprint f;
  for (const auto& p : tissue.mesh.rest_positions_mm) {
    f.min = f.min.cwiseMin(p.head<2>());
    f.max = f.max.cwiseMax(p.head<2>());
    f.top_z = std::min(f.top_z, p.z());
  }
  return f;
}

sim::SkinSurface make_skin(const TissueCase& tissue, const sim::SkinSettings& settings) {
  const Footprint f = footprint(tissue);
  return sim::SkinSurface(f.min, f.max, f.top_z, settings);
}

std::vector<Eigen::Vector3d> driven_rest(const sim::SkinSurface& skin) {
  std::vector<Eigen::Vector3d> out;
  for (auto n : skin.driven_nodes())
    out.push_back(skin.rest_positions_mm()[static_cast<std::size_t>(n)]);
  return out;
}

}  // namespace

DeformableSkin::DeformableSkin(const TissueCase& tissue, const sim::SkinSettings& settings)
    : skin_(make_skin(tissue, settings)),
      embedding_(tissue.mesh, driven_rest(skin_)),
      driven_(skin_.driven_nodes().size()) {
  const auto t = skin_.triangles();
  for (std::size_t i = 0; i < t.size(); i += 3) {
    triangles_.push_back({static_cast<std::int32_t>(t[i]), static_cast<std::int32_t>(t[i + 1]),
                          static_cast<std::int32_t>(t[i + 2])});
  }
  indices_.assign(t.begin(), t.end());
  normals_.resize(static_cast<std::size_t>(skin_.node_count()));
  positions_f_.resize(3 * normals_.size());
  normals_f_.resize(3 * normals_.size());
  view_.positions_mm = positions_f_;
  view_.normals = normals_f_;
  view_.triangles = indices_;
  view_.rgba = {0.93f, 0.76f, 0.66f, 0.28f};  // skin, translucent: the vessels show through
  view_.skin = true;                          // cut away when the trainee looks at the bare tissue
  refresh_view();
}

void DeformableSkin::step(std::span<const Eigen::Vector3d> deformed_nodes_mm,
                          const sim::ProbeCollider* probe, double dt_s) {
  embedding_.update(deformed_nodes_mm, driven_);
  skin_.step(probe, driven_, dt_s);
  refresh_view();
}

void DeformableSkin::refresh_view() {
  const auto p = skin_.positions_mm();
  geometry::compute_vertex_normals(p, triangles_, normals_);
  for (std::size_t v = 0; v < p.size(); ++v) {
    for (int a = 0; a < 3; ++a) {
      positions_f_[3 * v + a] = static_cast<float>(p[v][a]);
      normals_f_[3 * v + a] = static_cast<float>(normals_[v][a]);
    }
  }
}

}  // namespace ultrasim::kiosk
