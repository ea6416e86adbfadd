#include "ultrasim/config/case_settings.hpp"

#include <cstddef>
#include <system_error>

#include "document_schema.hpp"
#include "path_codec.hpp"
#include "scalar_codecs.hpp"
#include "toml_document.hpp"

namespace ultrasim::config {
namespace {

// Label volumes are uchar (docs/case-format.md), so every label value fits in [0, 255].
constexpr IntegerIn<int> kLabel{0, 255};

using Point3 = FixedArray<RealIn, 3>;

TableSchema<CaseSettings> case_schema() {
  using S = CaseSettings;
  TableSchema<S> t;
  t.add(field("name", &S::name, Text{.non_empty = true}, "Shown in the case list.",
              Presence::kRequired));
  t.add(field("description", &S::description, Text{}, "One line about the case."));
  t.add(field("volume", &S::volume_path, ExistingFile{},
              "B-mode echo intensities (MetaImage .mha, uchar).", Presence::kRequired));
  t.add(field("labels", &S::labels_path, ExistingFile{},
              "Tissue labels (MetaImage .mha, uchar), same grid as volume.", Presence::kRequired));
  return t;
}

// The axis names used in messages about per-axis rules.
constexpr const char* kAxisNames[3] = {"x", "y", "z"};

void check_region(const CaseMesh& mesh, const toml::table& table, const ReadContext& ctx,
                  const std::string& table_key) {
  const bool has_min = mesh.region_min_mm.has_value();
  const bool has_max = mesh.region_max_mm.has_value();
  const std::string allowed = "region_min_mm < region_max_mm on every axis, both set or neither";
  if (has_min != has_max) {
    const char* present = has_min ? "region_min_mm" : "region_max_mm";
    const char* absent = has_min ? "region_max_mm" : "region_min_mm";
    fail_at(ctx, table.get(present)->source(), dotted(table_key, present),
            std::string("set without ") + absent, allowed);
  }
  if (!has_min) return;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const double lo = (*mesh.region_min_mm)[axis];
    const double hi = (*mesh.region_max_mm)[axis];
    if (lo < hi) continue;
    const toml::node& max_node = *table.get_as<toml::array>("region_max_mm")->get(axis);
    fail_at(ctx, max_node.source(), element_key(dotted(table_key, "region_max_mm"), axis),
            std::string("not greater than region_min_mm on ") + kAxisNames[axis] + " (" +
                toml_real(lo) + " >= " + toml_real(hi) + ")",
            allowed);
  }
}

void check_split(const CaseMesh& mesh, const toml::table& table, const ReadContext& ctx,
                 const std::string& table_key) {
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const int parts = mesh.sub_volumes[axis];
    if (parts == 1 || mesh.nodes[axis] - mesh.overlap_nodes >= parts) continue;
    const toml::node& node = *table.get_as<toml::array>("sub_volumes")->get(axis);
    fail_at(ctx, node.source(), element_key(dotted(table_key, "sub_volumes"), axis),
            std::to_string(parts) + " sub-volumes on " + kAxisNames[axis] + " do not fit " +
                std::to_string(mesh.nodes[axis]) + " nodes overlapping by " +
                std::to_string(mesh.overlap_nodes),
            "at most nodes - overlap_nodes sub-volumes per axis");
  }
}

TableSchema<CaseMesh> mesh_schema() {
  using S = CaseMesh;
  TableSchema<S> t;
  t.add(field("nodes", &S::nodes, FixedArray<IntegerIn<int>, 3>{IntegerIn<int>{2, 512}},
              "Grid nodes along x, y, z.", Presence::kRequired));
  t.add(field("region_min_mm", &S::region_min_mm, Point3{RealIn::finite()},
              "Simulated region, lower corner in mm; unset: the volume's extent."));
  t.add(field("region_max_mm", &S::region_max_mm, Point3{RealIn::finite()},
              "Simulated region, upper corner in mm; unset: the volume's extent."));
  t.add(field("fixed_faces", &S::fixed_faces,
              List<Choice<BoxFace>>{.element = {{{"x_min", BoxFace::kXMin},
                                                 {"x_max", BoxFace::kXMax},
                                                 {"y_min", BoxFace::kYMin},
                                                 {"y_max", BoxFace::kYMax},
                                                 {"z_min", BoxFace::kZMin},
                                                 {"z_max", BoxFace::kZMax}}},
                                    .unique = true},
              "Faces of the region whose nodes do not move."));
  t.add(field("fix_label", &S::fix_label, List<IntegerIn<int>>{.element = kLabel, .unique = true},
              "Nodes inside these labels (e.g. bone) do not move either."));
  t.add(field("material_mixing", &S::material_mixing,
              Choice<sim::MaterialMixing>{{{"centroid", sim::MaterialMixing::kCentroid},
                                           {"reuss", sim::MaterialMixing::kReuss}}},
              "A tet cut by several labels: the label at its centroid (published), or the Reuss "
              "average of its tissues by volume."));
  t.add(field("sub_volumes", &S::sub_volumes, FixedArray<IntegerIn<int>, 3>{IntegerIn<int>{1, 64}},
              "Volume stitching: sub-volumes along x, y, z ([1, 1, 1]: one piece). Methods pcg, "
              "msds-explicit and msds-implicit then run stitched; the others are refused."));
  t.add(field("overlap_nodes", &S::overlap_nodes, IntegerIn<int>{1, 8},
              "Node layers neighbouring sub-volumes share (published: 2)."));
  t.check(check_region);
  t.check(check_split);
  return t;
}

TableSchema<sim::Material> material_schema() {
  using S = sim::Material;
  TableSchema<S> t;
  t.add(field("label", &S::label, kLabel, "Label value in the label volume.", Presence::kRequired));
  t.add(field("name", &S::name, Text{.non_empty = true}, "Tissue name.", Presence::kRequired));
  t.add(field("youngs_modulus_kpa", &S::youngs_modulus_kpa, RealIn::open_closed(0.0, 1e7),
              "Young's modulus E in kPa (fat ~1, tendon ~1e6).", Presence::kRequired));
  t.add(field("poisson_ratio", &S::poisson_ratio, RealIn::closed_open(0.0, 0.5),
              "Poisson's ratio; near 0.5 is near-incompressible."));
  t.add(field("stiffening", &S::stiffening, RealIn::closed(0.0, 50.0),
              "How fast the tissue stiffens as it is squeezed (hyperelastic FEM only; 0 = "
              "neo-Hookean)."));
  return t;
}

TableSchema<imaging::ProbeGeometry> probe_schema() {
  using S = imaging::ProbeGeometry;
  TableSchema<S> t;
  t.add(field("kind", &S::kind,
              Choice<imaging::ProbeKind>{{{"linear", imaging::ProbeKind::kLinear},
                                          {"convex", imaging::ProbeKind::kConvex}}},
              "Transducer kind."));
  t.add(field("width_mm", &S::width_mm, RealIn::open_closed(0.0, 200.0),
              "Linear: aperture width in mm."));
  t.add(field("depth_mm", &S::depth_mm, RealIn::open_closed(0.0, 300.0),
              "Imaging depth below the face in mm."));
  t.add(field("radius_mm", &S::radius_mm, RealIn::open_closed(0.0, 200.0),
              "Convex: radius of curvature of the face in mm."));
  t.add(field("fan_angle_deg", &S::fan_angle_deg, RealIn::open_closed(0.0, 180.0),
              "Convex: total opening angle of the sector in degrees."));
  return t;
}

TableSchema<CaseScan> scan_schema() {
  using S = CaseScan;
  TableSchema<S> t;
  t.add(field("start_mm", &S::start_mm, Point3{RealIn::finite()},
              "Probe face centre at the start of the sweep, mm.", Presence::kRequired));
  t.add(field("end_mm", &S::end_mm, Point3{RealIn::finite()},
              "Probe face centre at the end of the sweep, mm.", Presence::kRequired));
  t.add(field("press_depth_mm", &S::press_depth_mm, RealIn::closed(0.0, 50.0),
              "How far the probe presses into the skin at the press, mm."));
  return t;
}

// Two materials for one label would make the label -> material map ambiguous.
void check_unique_labels(const CaseSettings& settings, const toml::table& root,
                         const ReadContext& ctx) {
  for (std::size_t i = 0; i < settings.materials.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (settings.materials[i].label != settings.materials[j].label) continue;
      const std::string key = element_key("materials", i) + ".label";
      const toml::node* first = node_at(root, element_key("materials", j) + ".label");
      fail_at(ctx, node_at(root, key)->source(), key,
              "duplicate label " + std::to_string(settings.materials[i].label) +
                  " (also materials[" + std::to_string(j) + "] at line " +
                  std::to_string(first->source().begin.line) + ")",
              "each label in at most one [[materials]] table");
    }
  }
}

const DocumentSchema<CaseSettings>& document_schema() {
  // Built once, read-only afterwards: safe to share between threads.
  static const DocumentSchema<CaseSettings> schema = [] {
    DocumentSchema<CaseSettings> d({"ultrasim case (docs/case-format.md)."});
    d.table("case", case_schema(), "The case and its volumes.");
    d.table("mesh", &CaseSettings::mesh, mesh_schema(),
            "The regular tetrahedral grid over the simulated region.");
    d.table_array("materials", &CaseSettings::materials, material_schema(), 1,
                  "One material per label that occurs in the mesh region.");
    d.table("probe", &CaseSettings::probe, probe_schema(), "The transducer's geometry.");
    d.table("scan", &CaseSettings::scan, scan_schema(),
            "The scripted probe's path over this case (headless runs).");
    d.check(check_unique_labels);
    return d;
  }();
  return schema;
}

}  // namespace

CaseSettings parse_case_settings(std::string_view toml_text, std::string_view source_name,
                                 const std::filesystem::path& case_dir) {
  const toml::table root = parse_toml(toml_text, source_name);
  return document_schema().read(
      root, ReadContext{.source_name = std::string(source_name), .base_dir = case_dir});
}

CaseSettings load_case_settings(const std::filesystem::path& case_dir_or_toml_path) {
  std::error_code error;  // unreadable paths are reported by read_text_file below
  std::filesystem::path toml_path = case_dir_or_toml_path;
  // A path that is not a .toml file names a case folder, whether or not it exists, so a missing
  // folder is reported as its missing case.toml.
  if (std::filesystem::is_directory(toml_path, error) || toml_path.extension() != ".toml") {
    toml_path /= "case.toml";
  }
  std::filesystem::path absolute = std::filesystem::absolute(toml_path, error);
  if (error) absolute = toml_path;
  const std::filesystem::path case_dir = absolute.lexically_normal().parent_path();
  return parse_case_settings(read_text_file(toml_path), toml_path.string(), case_dir);
}

std::string format_case_toml(const CaseSettings& settings, const std::filesystem::path& case_dir) {
  return document_schema().write(settings, WriteContext{.base_dir = case_dir});
}

}  // namespace ultrasim::config
