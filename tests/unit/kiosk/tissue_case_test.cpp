#include "ultrasim/kiosk/tissue_case.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "tiny_case.hpp"
#include "ultrasim/config/config_error.hpp"
#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/kiosk/session.hpp"

namespace ultrasim::kiosk {
namespace {

using testing::tiny_case_toml;
using testing::TinyCase;

TEST(TissueCase, MeshesTheCaseWithMaterialsFromLabelsAndFixedNodes) {
  const TinyCase files;
  const TissueCase c = load_tissue_case(files.dir());
  EXPECT_EQ(c.mesh.node_count(), 125);
  EXPECT_EQ(c.mesh.tet_count(), 320);
  ASSERT_EQ(c.tet_materials.size(), 320u);
  int vein_tets = 0;
  for (const auto& m : c.tet_materials) vein_tets += m.name == "vein";
  EXPECT_GT(vein_tets, 0);
  EXPECT_LT(vein_tets, 320);
  int fixed = 0;
  for (std::size_t n = 0; n < c.fixed_nodes.size(); ++n) {
    fixed += c.fixed_nodes[n];
    EXPECT_EQ(c.fixed_nodes[n] != 0, c.mesh.rest_positions_mm[n].z() == 20.0);
  }
  EXPECT_EQ(fixed, 25);
  ASSERT_FALSE(c.line_levels.empty());
  EXPECT_FALSE(c.line_levels.front().empty()) << "the surface's tet edges";
  // The wireframe's nodes are the surface's, its lines index them, its levels coarsen.
  EXPECT_EQ(c.view_nodes.size(), 125u - 27u);
  for (std::uint32_t n : c.view_nodes) {
    const Eigen::Vector3d& p = c.mesh.rest_positions_mm[n];
    const bool on_box = (p.array() == c.mesh.rest_positions_mm.front().array()).any() ||
                        (p.array() == c.mesh.rest_positions_mm.back().array()).any();
    EXPECT_TRUE(on_box) << "node " << n << " is inside";
  }
  ASSERT_EQ(c.line_levels.size(), c.line_level_spacing_mm.size());
  ASSERT_GE(c.line_levels.size(), 3u);
  for (std::size_t l = 0; l < c.line_levels.size(); ++l) {
    for (std::uint32_t i : c.line_levels[l]) ASSERT_LT(i, c.view_nodes.size());
    if (l > 0) {
      EXPECT_LT(c.line_levels[l].size(), c.line_levels[l - 1].size());
      EXPECT_GT(c.line_level_spacing_mm[l], c.line_level_spacing_mm[l - 1]);
    }
  }
}

void expect_error_mentions(const std::function<void()>& load,
                           const std::vector<std::string>& words) {
  try {
    load();
    ADD_FAILURE() << "expected an error";
  } catch (const std::exception& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
    for (const auto& w : words) EXPECT_NE(message.find(w), std::string::npos) << message;
  }
}

TEST(TissueCase, ANoFixedNodeCaseIsRejectedBeforeItCanBeSolved) {
  const TinyCase files(tiny_case_toml("[]"));
  const TissueCase c = load_tissue_case(files.dir());
  const hal::ManualClock clock;
  hal::InlineJobSystem jobs;
  expect_error_mentions([&] { Session session(c, config::AppSettings{}, clock, jobs); },
                        {"no fixed nodes", "singular"});
}

TEST(TissueCase, ALabelWithoutAMaterialNamesTheFileAndTheLabel) {
  const TinyCase files(tiny_case_toml("[\"z_max\"]", false));
  expect_error_mentions([&] { load_tissue_case(files.dir()); },
                        {"case.toml", "[[materials]]", "label 4"});
}

TEST(TissueCase, ACorruptVolumeNamesTheFile) {
  const TinyCase files;
  {
    std::ofstream truncate(files.dir() / "volume.mha", std::ios::trunc);
    truncate << "ObjectType = Image\nNDims = 3\nDimSize = 21 0 21\nElementType = MET_UCHAR\n"
                "ElementDataFile = LOCAL\n";
  }
  expect_error_mentions([&] { load_tissue_case(files.dir()); }, {"volume.mha:3", "DimSize"});
}

TEST(TissueCase, AMissingCaseNamesItsCaseToml) {
  expect_error_mentions([&] { load_tissue_case("/nonexistent/case-folder"); },
                        {"/nonexistent/case-folder/case.toml"});
}

}  // namespace
}  // namespace ultrasim::kiosk
