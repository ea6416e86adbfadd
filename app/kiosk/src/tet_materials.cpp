#include "ultrasim/kiosk/tet_materials.hpp"

#include <array>
#include <map>

#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/sim/material_mixing.hpp"

namespace ultrasim::kiosk {

namespace {

// Divisions per edge of the barycentric lattice a tet is sampled at for kReuss:
// (n + 1)(n + 2)(n + 3) / 6 = 84 points.
constexpr int kTetSampleDivisions = 6;

// Labels → materials, counting the tets whose label has none.
class MaterialTable {
 public:
  explicit MaterialTable(std::span<const sim::Material> materials) {
    for (const auto& m : materials) by_label_[m.label] = &m;
  }

  // The material of `label`, or nullptr (counted).
  const sim::Material* find(int label) {
    const auto it = by_label_.find(label);
    if (it != by_label_.end()) return it->second;
    ++missing_[label];
    return nullptr;
  }

  void throw_if_missing(const std::string& source) const {
    if (missing_.empty()) return;
    const auto& [label, count] = *missing_.begin();
    throw CaseError(source + ": [[materials]]: no entry for label " + std::to_string(label) +
                    ", which fills " + std::to_string(count) + " tets of the mesh");
  }

 private:
  std::map<int, const sim::Material*> by_label_;
  std::map<int, int> missing_;  // label → tets (or samples) without a material
};

sim::Material at_centroid(const geometry::TetMesh& mesh, const geometry::Tet& tet,
                          const imaging::Volume<std::uint8_t>& labels, MaterialTable& table) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (auto n : tet) centroid += mesh.rest_positions_mm[n] / 4.0;
  const sim::Material* m = table.find(labels.sample_nearest(centroid, 0));
  return m != nullptr ? *m : sim::Material{};
}

// The Reuss average over the tet's lattice points, each point an equal share of its volume.
sim::Material reuss_mixed(const geometry::TetMesh& mesh, const geometry::Tet& tet,
                          const imaging::Volume<std::uint8_t>& labels, MaterialTable& table,
                          std::vector<sim::Material>& phases, std::vector<double>& counts) {
  phases.clear();
  counts.clear();
  const auto& p = mesh.rest_positions_mm;
  constexpr int n = kTetSampleDivisions;
  for (int a = 0; a <= n; ++a) {
    for (int b = 0; a + b <= n; ++b) {
      for (int c = 0; a + b + c <= n; ++c) {
        const int d = n - a - b - c;
        const Eigen::Vector3d q =
            (a * p[tet[0]] + b * p[tet[1]] + c * p[tet[2]] + d * p[tet[3]]) / n;
        const sim::Material* m = table.find(labels.sample_nearest(q, 0));
        if (m == nullptr) return sim::Material{};
        std::size_t i = 0;
        while (i < phases.size() && phases[i].label != m->label) ++i;
        if (i == phases.size()) {
          phases.push_back(*m);
          counts.push_back(0.0);
        }
        counts[i] += 1.0;
      }
    }
  }
  return sim::reuss_average(phases, counts);
}

}  // namespace

std::vector<sim::Material> tet_materials(const geometry::TetMesh& mesh,
                                         const imaging::Volume<std::uint8_t>& labels,
                                         std::span<const sim::Material> materials,
                                         sim::MaterialMixing mixing, const std::string& source) {
  MaterialTable table(materials);
  std::vector<sim::Material> out;
  out.reserve(mesh.tets.size());
  std::vector<sim::Material> phases;
  std::vector<double> counts;
  for (const auto& tet : mesh.tets) {
    out.push_back(mixing == sim::MaterialMixing::kReuss
                      ? reuss_mixed(mesh, tet, labels, table, phases, counts)
                      : at_centroid(mesh, tet, labels, table));
  }
  table.throw_if_missing(source);
  return out;
}

}  // namespace ultrasim::kiosk
