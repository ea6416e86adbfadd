#include "ultrasim/config/case_settings.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "config_test_support.hpp"
#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config {
namespace {

using ::testing::ElementsAre;
using testing::error_of;
using ::testing::HasSubstr;
using testing::ScratchDir;

// The example of docs/case-format.md, verbatim.
constexpr std::string_view kExampleCase = R"(
[case]
name = "default-upper-arm"          # shown in the case list
description = "synthetic upper arm: vein beside artery, nerve, humerus"
volume = "volume.mha"               # B-mode echo intensities, uchar, path relative to this file
labels = "labels.mha"               # tissue labels as above, same grid as `volume`

[mesh]
nodes = [25, 9, 19]                 # grid nodes along x, y, z (each >= 2)
region_min_mm = [-30.0, -20.0, 0.0] # simulated region; defaults to the volume's extent
region_max_mm = [30.0, 20.0, 45.0]
fixed_faces = ["z_max"]             # any of x_min x_max y_min y_max z_min z_max
fix_label = [7]                     # nodes inside these labels (bone) are fixed too
material_mixing = "reuss"           # a tet cut by several labels: centroid (default) or reuss

[[materials]]                       # one per label that occurs in the mesh region
label = 1
name = "skin"
youngs_modulus_kpa = 150.0          # range (0, 1e7]
poisson_ratio = 0.45                # range [0, 0.5)

[probe]
kind = "linear"                     # "linear" or "convex"
width_mm = 38.0                     # linear aperture
depth_mm = 40.0                     # imaging depth
radius_mm = 50.0                    # convex only
fan_angle_deg = 60.0                # convex only

[scan]                              # the scripted probe's path over this case (headless runs)
start_mm = [-8.0, -12.0, 0.0]       # probe face centre at the start of the sweep
end_mm = [-8.0, 12.0, 0.0]          # ... and at its end (on the skin)
press_depth_mm = 8.0                # how far the probe presses into the skin at the press
)";

// A case folder with stand-in volume files (the loader checks only that they exist).
class CaseDir : public ScratchDir {
 public:
  CaseDir() {
    write("volume.mha", "stand-in");
    write("labels.mha", "stand-in");
  }
};

// The minimum a valid case needs, for tests that vary one part.
std::string minimal_case(std::string_view mesh_extra = "", std::string_view materials = "") {
  return std::string("[case]\nname = \"c\"\nvolume = \"volume.mha\"\nlabels = \"labels.mha\"\n") +
         "[mesh]\nnodes = [2, 3, 4]\n" + std::string(mesh_extra) +
         (materials.empty() ? std::string("[[materials]]\nlabel = 1\nname = \"skin\"\n"
                                          "youngs_modulus_kpa = 150.0\n")
                            : std::string(materials)) +
         "[scan]\nstart_mm = [0, 0, 0]\nend_mm = [0, 1, 0]\n";
}

void expect_same(const CaseSettings& a, const CaseSettings& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.description, b.description);
  EXPECT_EQ(a.volume_path, b.volume_path);
  EXPECT_EQ(a.labels_path, b.labels_path);
  EXPECT_EQ(a.mesh.nodes, b.mesh.nodes);
  EXPECT_EQ(a.mesh.region_min_mm, b.mesh.region_min_mm);
  EXPECT_EQ(a.mesh.region_max_mm, b.mesh.region_max_mm);
  EXPECT_EQ(a.mesh.fixed_faces, b.mesh.fixed_faces);
  EXPECT_EQ(a.mesh.fix_label, b.mesh.fix_label);
  EXPECT_EQ(a.mesh.material_mixing, b.mesh.material_mixing);
  EXPECT_EQ(a.mesh.sub_volumes, b.mesh.sub_volumes);
  EXPECT_EQ(a.mesh.overlap_nodes, b.mesh.overlap_nodes);
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    EXPECT_EQ(a.materials[i].label, b.materials[i].label);
    EXPECT_EQ(a.materials[i].name, b.materials[i].name);
    EXPECT_EQ(a.materials[i].youngs_modulus_kpa, b.materials[i].youngs_modulus_kpa);
    EXPECT_EQ(a.materials[i].poisson_ratio, b.materials[i].poisson_ratio);
  }
  EXPECT_EQ(a.probe.kind, b.probe.kind);
  EXPECT_EQ(a.probe.width_mm, b.probe.width_mm);
  EXPECT_EQ(a.probe.depth_mm, b.probe.depth_mm);
  EXPECT_EQ(a.probe.radius_mm, b.probe.radius_mm);
  EXPECT_EQ(a.probe.fan_angle_deg, b.probe.fan_angle_deg);
  EXPECT_EQ(a.scan.start_mm, b.scan.start_mm);
  EXPECT_EQ(a.scan.end_mm, b.scan.end_mm);
  EXPECT_EQ(a.scan.press_depth_mm, b.scan.press_depth_mm);
}

TEST(CaseSettings, LoadsTheDocumentedExampleFromItsFolder) {
  const CaseDir dir;
  dir.write("case.toml", kExampleCase);
  const CaseSettings c = load_case_settings(dir.path());
  EXPECT_EQ(c.name, "default-upper-arm");
  EXPECT_EQ(c.description, "synthetic upper arm: vein beside artery, nerve, humerus");
  EXPECT_EQ(c.volume_path, (dir.path() / "volume.mha").lexically_normal());
  EXPECT_EQ(c.labels_path, (dir.path() / "labels.mha").lexically_normal());
  EXPECT_EQ(c.mesh.nodes, (std::array<int, 3>{25, 9, 19}));
  EXPECT_EQ(c.mesh.region_min_mm, (std::array<double, 3>{-30.0, -20.0, 0.0}));
  EXPECT_EQ(c.mesh.region_max_mm, (std::array<double, 3>{30.0, 20.0, 45.0}));
  EXPECT_THAT(c.mesh.fixed_faces, ElementsAre(BoxFace::kZMax));
  EXPECT_THAT(c.mesh.fix_label, ElementsAre(7));
  EXPECT_EQ(c.mesh.material_mixing, sim::MaterialMixing::kReuss);
  ASSERT_EQ(c.materials.size(), 1u);
  EXPECT_EQ(c.materials[0].label, 1);
  EXPECT_EQ(c.materials[0].name, "skin");
  EXPECT_EQ(c.materials[0].youngs_modulus_kpa, 150.0);
  EXPECT_EQ(c.materials[0].poisson_ratio, 0.45);
  EXPECT_EQ(c.probe.kind, imaging::ProbeKind::kLinear);
  EXPECT_EQ(c.probe.width_mm, 38.0);
  EXPECT_EQ(c.probe.depth_mm, 40.0);
  EXPECT_EQ(c.probe.radius_mm, 50.0);
  EXPECT_EQ(c.probe.fan_angle_deg, 60.0);
  EXPECT_EQ(c.scan.start_mm, (std::array<double, 3>{-8.0, -12.0, 0.0}));
  EXPECT_EQ(c.scan.end_mm, (std::array<double, 3>{-8.0, 12.0, 0.0}));
  EXPECT_EQ(c.scan.press_depth_mm, 8.0);
}

TEST(CaseSettings, AcceptsThePathOfCaseTomlItself) {
  const CaseDir dir;
  const auto toml_path = dir.write("other-name.toml", kExampleCase);
  EXPECT_EQ(load_case_settings(toml_path).volume_path,
            (dir.path() / "volume.mha").lexically_normal());
}

TEST(CaseSettings, OptionalPartsKeepDefaults) {
  const CaseDir dir;
  const CaseSettings c = parse_case_settings(minimal_case(), "case.toml", dir.path());
  EXPECT_EQ(c.description, "");
  EXPECT_FALSE(c.mesh.region_min_mm.has_value());
  EXPECT_FALSE(c.mesh.region_max_mm.has_value());
  EXPECT_TRUE(c.mesh.fixed_faces.empty());
  EXPECT_TRUE(c.mesh.fix_label.empty());
  EXPECT_EQ(c.mesh.material_mixing, sim::MaterialMixing::kCentroid);
  EXPECT_EQ(c.mesh.sub_volumes, (std::array<int, 3>{1, 1, 1}));
  EXPECT_EQ(c.mesh.overlap_nodes, 2);
  EXPECT_EQ(c.materials.at(0).poisson_ratio, sim::Material{}.poisson_ratio);
  EXPECT_EQ(c.probe.kind, imaging::ProbeGeometry{}.kind);
  EXPECT_EQ(c.probe.width_mm, imaging::ProbeGeometry{}.width_mm);
  EXPECT_EQ(c.scan.press_depth_mm, CaseScan{}.press_depth_mm);
}

TEST(CaseSettings, EveryFieldRoundTripsThroughFormat) {
  const CaseDir dir;
  std::filesystem::create_directories(dir.path() / "sub");
  dir.write("sub/labels.mha", "stand-in");
  CaseSettings c;
  c.name = "round \"trip\"";
  c.description = "every field set";
  c.volume_path = (dir.path() / "volume.mha").lexically_normal();
  c.labels_path = (dir.path() / "sub" / "labels.mha").lexically_normal();
  c.mesh.nodes = {3, 4, 512};
  c.mesh.region_min_mm = std::array<double, 3>{-1.5, -2.25, 0.1};
  c.mesh.region_max_mm = std::array<double, 3>{1.5, 2.25, 30.0};
  c.mesh.fixed_faces = {BoxFace::kXMin, BoxFace::kXMax, BoxFace::kYMin,
                        BoxFace::kYMax, BoxFace::kZMin, BoxFace::kZMax};
  c.mesh.fix_label = {7, 0, 255};
  c.mesh.material_mixing = sim::MaterialMixing::kReuss;
  c.mesh.sub_volumes = {1, 2, 64};
  c.mesh.overlap_nodes = 1;
  c.materials = {{.label = 1, .name = "skin", .youngs_modulus_kpa = 150.0, .poisson_ratio = 0.45},
                 {.label = 4, .name = "vein", .youngs_modulus_kpa = 1e7, .poisson_ratio = 0.0}};
  c.probe = {.kind = imaging::ProbeKind::kConvex,
             .width_mm = 20.0,
             .depth_mm = 300.0,
             .radius_mm = 0.1,
             .fan_angle_deg = 180.0};
  c.scan = {.start_mm = {-8.0, -12.0, 0.0}, .end_mm = {8.0, 12.0, 0.5}, .press_depth_mm = 50.0};
  const std::string text = format_case_toml(c, dir.path());
  EXPECT_THAT(text, HasSubstr("labels = \"sub/labels.mha\""));  // relative, so the folder moves
  expect_same(parse_case_settings(text, "formatted.toml", dir.path()), c);
}

TEST(CaseSettings, MissingVolumeFileNamesThePath) {
  const ScratchDir dir;  // no volume files in it
  dir.write("case.toml", kExampleCase);
  const auto caught = error_of([&] { (void)load_case_settings(dir.path()); });
  const std::string expected_path = (dir.path() / "volume.mha").lexically_normal().string();
  EXPECT_THAT(caught.message,
              HasSubstr("case.toml:5:10: case.volume: file not found: " + expected_path));
}

TEST(CaseSettings, MissingCaseTomlIsAnError) {
  const ScratchDir dir;
  const auto caught = error_of([&] { (void)load_case_settings(dir.path()); });
  EXPECT_THAT(caught.message, HasSubstr((dir.path() / "case.toml").string()));
}

TEST(CaseSettings, DuplicateMaterialLabelsAreAnError) {
  const CaseDir dir;
  const std::string materials =
      "[[materials]]\nlabel = 4\nname = \"vein\"\nyoungs_modulus_kpa = 10\n"
      "[[materials]]\nlabel = 5\nname = \"artery\"\nyoungs_modulus_kpa = 100\n"
      "[[materials]]\nlabel = 4\nname = \"vein again\"\nyoungs_modulus_kpa = 20\n";
  const auto caught = error_of(
      [&] { (void)parse_case_settings(minimal_case("", materials), "case.toml", dir.path()); });
  EXPECT_EQ(caught.details.key, "materials[2].label");
  EXPECT_EQ(caught.details.line, 16);
  EXPECT_THAT(caught.message, HasSubstr("duplicate label 4 (also materials[0] at line 8)"));
}

TEST(CaseSettings, AtLeastOneMaterial) {
  const CaseDir dir;
  const std::string text =
      "[case]\nname = \"c\"\nvolume = \"volume.mha\"\nlabels = \"labels.mha\"\n"
      "[mesh]\nnodes = [2, 3, 4]\n[scan]\nstart_mm = [0, 0, 0]\nend_mm = [0, 1, 0]\n";
  const auto caught = error_of([&] { (void)parse_case_settings(text, "case.toml", dir.path()); });
  EXPECT_EQ(caught.details.key, "materials");
  EXPECT_THAT(caught.message, HasSubstr("missing required table"));
}

TEST(CaseSettings, MaterialRangesAreChecked) {
  const CaseDir dir;
  const auto caught = error_of([&] {
    (void)parse_case_settings(
        minimal_case("",
                     "[[materials]]\nlabel = 1\nname = \"x\"\nyoungs_modulus_kpa = 1\n"
                     "poisson_ratio = 0.5\n"),
        "case.toml", dir.path());
  });
  EXPECT_EQ(caught.details.key, "materials[0].poisson_ratio");
  EXPECT_EQ(caught.details.allowed, "number in [0, 0.5)");
}

TEST(CaseSettings, RegionMinMustBeBelowMaxOnEveryAxis) {
  const CaseDir dir;
  const auto caught = error_of([&] {
    (void)parse_case_settings(
        minimal_case("region_min_mm = [0, 0, 10]\nregion_max_mm = [1, 1, 10]\n"), "case.toml",
        dir.path());
  });
  EXPECT_EQ(caught.details.key, "mesh.region_max_mm[2]");
  EXPECT_EQ(caught.details.line, 8);
  EXPECT_THAT(caught.message, HasSubstr("not greater than region_min_mm on z (10.0 >= 10.0)"));
}

TEST(CaseSettings, RegionNeedsBothCorners) {
  const CaseDir dir;
  const auto caught = error_of([&] {
    (void)parse_case_settings(minimal_case("region_max_mm = [1, 1, 10]\n"), "case.toml",
                              dir.path());
  });
  EXPECT_EQ(caught.details.key, "mesh.region_max_mm");
  EXPECT_THAT(caught.message, HasSubstr("set without region_min_mm"));
}

TEST(CaseSettings, MissingRequiredKeyPointsAtItsTable) {
  const CaseDir dir;
  const std::string text =
      "[case]\nname = \"c\"\nvolume = \"volume.mha\"\nlabels = \"labels.mha\"\n\n"
      "[mesh]\nfixed_faces = []\n"
      "[[materials]]\nlabel = 1\nname = \"skin\"\nyoungs_modulus_kpa = 150.0\n";
  const auto caught = error_of([&] { (void)parse_case_settings(text, "case.toml", dir.path()); });
  EXPECT_EQ(caught.message,
            "case.toml:6:1: mesh.nodes: missing required key; allowed: array of 3, each integer "
            "in [2, 512]");
}

TEST(CaseSettings, NodesNeedThreeValuesInRange) {
  const CaseDir dir;
  auto with_nodes = [](std::string_view nodes) {
    return "[case]\nname = \"c\"\nvolume = \"volume.mha\"\nlabels = \"labels.mha\"\n"
           "[mesh]\nnodes = " +
           std::string(nodes) +
           "\n[[materials]]\nlabel = 1\nname = \"skin\"\nyoungs_modulus_kpa = 150.0\n"
           "[scan]\nstart_mm = [0, 0, 0]\nend_mm = [0, 1, 0]\n";
  };
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(with_nodes("[2, 3]"), "case.toml", dir.path());
              }).message,
              HasSubstr("mesh.nodes: wrong length: 2 elements"));
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(with_nodes("[2, 3, 1]"), "case.toml", dir.path());
              }).message,
              HasSubstr("mesh.nodes[2]: out of range: 1; allowed: integer in [2, 512]"));
}

TEST(CaseSettings, FixedFacesAreKnownNamesWithoutDuplicates) {
  const CaseDir dir;
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(minimal_case("fixed_faces = [\"top\"]\n"), "case.toml",
                                          dir.path());
              }).message,
              HasSubstr("mesh.fixed_faces[0]: unknown value \"top\"; allowed: one of \"x_min\", "
                        "\"x_max\", \"y_min\", \"y_max\", \"z_min\", \"z_max\""));
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(minimal_case("fixed_faces = [\"z_max\", \"z_max\"]\n"),
                                          "case.toml", dir.path());
              }).message,
              HasSubstr("mesh.fixed_faces[1]: duplicate value \"z_max\""));
}

TEST(CaseSettings, MaterialMixingIsAKnownRule) {
  const CaseDir dir;
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(minimal_case("material_mixing = \"voigt\"\n"),
                                          "case.toml", dir.path());
              }).message,
              HasSubstr("mesh.material_mixing: unknown value \"voigt\"; allowed: one of "
                        "\"centroid\", \"reuss\""));
}

TEST(CaseSettings, SubVolumesMustFitTheNodesWithTheirOverlap) {
  const CaseDir dir;
  // nodes = [2, 3, 4]: 3 nodes on y hold at most 3 - 2 = 1 sub-volume overlapping by 2.
  const auto caught = error_of([&] {
    (void)parse_case_settings(minimal_case("sub_volumes = [1, 2, 2]\n"), "case.toml", dir.path());
  });
  EXPECT_EQ(caught.details.key, "mesh.sub_volumes[1]");
  EXPECT_THAT(caught.message, HasSubstr("2 sub-volumes on y do not fit 3 nodes overlapping by 2"));
  // With one shared layer, 4 nodes on z take 2 (and 3 on y as well).
  const CaseSettings c = parse_case_settings(
      minimal_case("sub_volumes = [1, 2, 2]\noverlap_nodes = 1\n"), "case.toml", dir.path());
  EXPECT_EQ(c.mesh.sub_volumes, (std::array<int, 3>{1, 2, 2}));
  EXPECT_THAT(error_of([&] {
                (void)parse_case_settings(minimal_case("sub_volumes = [0, 1, 1]\n"), "case.toml",
                                          dir.path());
              }).message,
              HasSubstr("mesh.sub_volumes[0]"));
}

TEST(CaseSettings, BadProbeKindListsAllowedValues) {
  const CaseDir dir;
  const auto caught = error_of([&] {
    (void)parse_case_settings(minimal_case() + "[probe]\nkind = \"phased\"\n", "case.toml",
                              dir.path());
  });
  EXPECT_THAT(caught.message,
              HasSubstr("probe.kind: unknown value \"phased\"; allowed: one of \"linear\", "
                        "\"convex\""));
}

TEST(CaseSettings, UnknownKeyInMaterialNamesElement) {
  const CaseDir dir;
  const auto caught = error_of([&] {
    (void)parse_case_settings(
        minimal_case("", "[[materials]]\nlabel = 1\nname = \"x\"\nyoungs_modulus = 1\n"),
        "case.toml", dir.path());
  });
  EXPECT_EQ(caught.details.key, "materials[0].youngs_modulus");
  EXPECT_THAT(caught.message, HasSubstr("did you mean \"youngs_modulus_kpa\"?"));
}

}  // namespace
}  // namespace ultrasim::config
