// The embedded default case: deterministic, labels where docs/case-format.md and the brief put
// them, brightness ordered as in a real B-mode image of the arm, shadow under the bone, and a
// case.toml the documented format accepts.

#include "ultrasim/tools/make_case/default_case.hpp"

#include <gtest/gtest.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <set>

#include "ultrasim/imaging/metaimage.hpp"
#include "ultrasim/tools/make_case/case_toml.hpp"

namespace ultrasim::tools {
namespace {

std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  std::string bytes(static_cast<std::size_t>(std::max<std::streamoff>(in.tellg(), 0)), '\0');
  in.seekg(0);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            (std::string("ultrasim_tools_") + info->name() + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// The case at 0.5 mm (1/8 of the voxels of the shipped 0.25 mm case, same anatomy), made once.
class DefaultCase : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    DefaultCaseSettings settings;
    settings.spacing_mm = 0.5;
    generated_ = new GeneratedCase(generate_default_case(settings));
  }
  static void TearDownTestSuite() {
    delete generated_;
    generated_ = nullptr;
  }
  static const GeneratedCase& gen() { return *generated_; }
  static std::uint8_t label(double x, double y, double z) {
    return gen().labels.sample_nearest(Eigen::Vector3d(x, y, z), 255);
  }
  // Mean echo over voxels that satisfy pred(label, world point).
  template <typename Pred>
  static double mean_echo(Pred pred) {
    const auto& labels = gen().labels;
    double sum = 0.0;
    std::size_t count = 0;
    for (int k = 0; k < labels.size().z(); ++k) {
      for (int j = 0; j < labels.size().y(); ++j) {
        for (int i = 0; i < labels.size().x(); ++i) {
          const Eigen::Vector3d p = labels.index_to_world(Eigen::Vector3d(i, j, k));
          if (!pred(labels.at(i, j, k), p)) continue;
          sum += gen().echo.at(i, j, k);
          ++count;
        }
      }
    }
    EXPECT_GT(count, 50u) << "too few voxels to average";
    return count ? sum / static_cast<double>(count) : 0.0;
  }

  static GeneratedCase* generated_;
  const ArmPhantom phantom_{ArmAnatomy{}};
};

GeneratedCase* DefaultCase::generated_ = nullptr;

TEST_F(DefaultCase, GridCoversThePatientBox) {
  EXPECT_EQ(gen().labels.size(), Eigen::Vector3i(121, 81, 91));
  EXPECT_EQ(gen().echo.size(), gen().labels.size());
  EXPECT_TRUE(gen().labels.world_min_mm().isApprox(Eigen::Vector3d(-30, -20, 0)));
  EXPECT_TRUE(gen().labels.world_max_mm().isApprox(Eigen::Vector3d(30, 20, 45)));
}

TEST_F(DefaultCase, LabelsAtTheDocumentedPlaces) {
  EXPECT_EQ(label(0, 0, 1), kSkin);
  EXPECT_EQ(label(0, 0, 5), kFat);
  EXPECT_EQ(label(-20, 0, 25), kMuscle);
  EXPECT_EQ(label(-8, 0, 11), kVein);
  EXPECT_EQ(label(6, 0, 19), kArtery);
  EXPECT_EQ(label(15, 0, 13), kNerve);
  EXPECT_EQ(label(1, 0, 40), kBone);
  // Sizes: vein 4 × 2.2 mm semi-axes, artery lumen 3.5 + wall 1.2, nerve r 2.5, bone top 34.
  EXPECT_EQ(label(-8 + 3.5, 0, 11), kVein);
  EXPECT_EQ(label(-8 + 4.5, 0, 11), kMuscle);
  EXPECT_EQ(label(-8, 0, 11 + 2.0), kVein);
  EXPECT_EQ(label(-8, 0, 11 + 2.8), kMuscle);
  EXPECT_EQ(label(6 + 4.5, 0, 19), kArtery);
  EXPECT_EQ(label(6 + 5.5, 0, 19), kMuscle);
  EXPECT_EQ(label(15, 0, 13 + 3.0), kMuscle);
  EXPECT_EQ(label(1, 0, 33.5), kMuscle);
  EXPECT_EQ(label(1, 0, 34.5), kBone);
  // The vessels curve along the limb and the labels follow them.
  for (const double y : {-15.0, -7.5, 7.5, 15.0}) {
    const Eigen::Vector2d vein = phantom_.vein_centre_mm(y);
    const Eigen::Vector2d artery = phantom_.artery_centre_mm(y);
    const Eigen::Vector2d nerve = phantom_.nerve_centre_mm(y);
    EXPECT_EQ(label(vein.x(), y, vein.y()), kVein) << y;
    EXPECT_EQ(label(artery.x(), y, artery.y()), kArtery) << y;
    EXPECT_EQ(label(nerve.x(), y, nerve.y()), kNerve) << y;
  }
  EXPECT_NE(phantom_.vein_centre_mm(-15.0), phantom_.vein_centre_mm(15.0));
}

TEST_F(DefaultCase, EveryTissueLabelOccursAndNothingElse) {
  std::set<int> seen;
  for (const auto v : gen().labels.voxels()) seen.insert(v);
  EXPECT_EQ(seen, (std::set<int>{1, 2, 3, 4, 5, 6, 7}));
}

TEST_F(DefaultCase, LabelsAreExactNotBlurred) {
  // The label volume is the phantom sampled at voxel centres, nothing else.
  const auto& labels = gen().labels;
  for (int k = 0; k < labels.size().z(); k += 3) {
    for (int j = 0; j < labels.size().y(); j += 5) {
      for (int i = 0; i < labels.size().x(); i += 2) {
        ASSERT_EQ(labels.at(i, j, k),
                  phantom_.label_at(labels.index_to_world(Eigen::Vector3d(i, j, k))));
      }
    }
  }
}

TEST_F(DefaultCase, BrightnessOrderedLikeBMode) {
  const ArmPhantom& ph = phantom_;
  const double lumen = mean_echo([&](int l, const Eigen::Vector3d& p) {
    const Eigen::Vector2d v = ph.vein_centre_mm(p.y()), a = ph.artery_centre_mm(p.y());
    return (l == kVein && std::hypot((p.x() - v.x()) / 4.0, (p.z() - v.y()) / 2.2) < 0.6) ||
           (l == kArtery && std::hypot(p.x() - a.x(), p.z() - a.y()) < 2.5);
  });
  const double fat = mean_echo([](int l, const Eigen::Vector3d&) { return l == kFat; });
  const double muscle = mean_echo([](int l, const Eigen::Vector3d&) { return l == kMuscle; });
  const double skin = mean_echo([](int l, const Eigen::Vector3d&) { return l == kSkin; });
  // The top of the humerus, where the beam meets it square: the first 0.5 mm of bone.
  const double bone_surface = mean_echo([&](int l, const Eigen::Vector3d& p) {
    const double top = ph.bone_centre_mm().y() - std::sqrt(144.0 - std::pow(p.x() - 1.0, 2));
    return l == kBone && std::abs(p.x() - 1.0) < 5.0 && p.z() - top < 0.5;
  });
  EXPECT_LT(lumen, 10.0);
  EXPECT_LT(lumen, fat);
  EXPECT_LT(fat, muscle);
  EXPECT_LT(muscle, skin);
  EXPECT_LT(skin, bone_surface);
  // The brief's levels: fat ~40, muscle ~80, skin ~170, bone surface ~240.
  EXPECT_NEAR(fat, 40.0, 12.0);
  EXPECT_NEAR(muscle, 80.0, 12.0);
  EXPECT_NEAR(skin, 165.0, 20.0);
  EXPECT_GT(bone_surface, 200.0);
}

TEST_F(DefaultCase, ShadowUnderTheBoneIsDark) {
  const Eigen::Vector2d c = phantom_.bone_centre_mm();
  const double shadow = mean_echo([&](int l, const Eigen::Vector3d& p) {
    const double top = c.y() - std::sqrt(144.0 - std::pow(p.x() - c.x(), 2));
    return l == kBone && std::abs(p.x() - c.x()) < 8.0 && p.z() - top > 3.0;
  });
  const double muscle_beside = mean_echo([&](int l, const Eigen::Vector3d& p) {
    return l == kMuscle && p.z() > 36.0 && std::abs(p.x() - c.x()) > 14.0;
  });
  EXPECT_LT(shadow, 0.2 * muscle_beside);
  EXPECT_LT(shadow, 12.0);
}

TEST_F(DefaultCase, PosteriorEnhancementBelowTheVein) {
  // Muscle just below the vein (blood above) against muscle at the same depth beside it.
  const auto band = [&](bool below) {
    return mean_echo([&, below](int l, const Eigen::Vector3d& p) {
      const Eigen::Vector2d v = phantom_.vein_centre_mm(p.y());
      const double dx = p.x() - v.x();
      return l == kMuscle && p.z() > v.y() + 3.0 && p.z() < v.y() + 6.5 &&
             (below ? std::abs(dx) < 3.0 : (dx < -9.0 && dx > -15.0));
    });
  };
  EXPECT_GT(band(true), 1.15 * band(false));
}

TEST(DefaultCaseDeterminism, SameSettingsSameFiles) {
  DefaultCaseSettings settings;
  settings.spacing_mm = 1.0;
  const ScratchDir a, b;
  write_case_folder(a.path() / "case", generate_default_case(settings));
  write_case_folder(b.path() / "case", generate_default_case(settings));
  for (const char* file : {"volume.mha", "labels.mha", "case.toml"}) {
    const std::string bytes = read_bytes(a.path() / "case" / file);
    EXPECT_GT(bytes.size(), 100u) << file;
    EXPECT_EQ(bytes, read_bytes(b.path() / "case" / file)) << file;
  }
  // What was written reads back as the generated volumes.
  const auto generated = generate_default_case(settings);
  const auto echo = imaging::read_volume_u8(a.path() / "case" / "volume.mha");
  EXPECT_TRUE(std::equal(echo.voxels().begin(), echo.voxels().end(),
                         generated.echo.voxels().begin(), generated.echo.voxels().end()));
}

TEST(DefaultCaseDeterminism, FixedVoxelHash) {
  // Pins the label volume at 1 mm (geometry only: no speckle) so an accidental change to the
  // anatomy shows up. Change the value deliberately when the anatomy changes on purpose (a libm
  // that rounds a sine differently could also flip a boundary voxel).
  DefaultCaseSettings settings;
  settings.spacing_mm = 1.0;
  const auto generated = generate_default_case(settings);
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const auto v : generated.labels.voxels()) h = (h ^ v) * 0x100000001b3ULL;
  EXPECT_EQ(h, 0xdda324ebbaf72820ULL) << "0x" << std::hex << h;
}

TEST(DefaultCaseToml, MatchesTheDocumentedFormat) {
  const std::string text = default_case_toml({-30, -20, 0}, {30, 20, 45});
  toml::table t;
  ASSERT_NO_THROW(t = toml::parse(text)) << text;
  EXPECT_EQ(t["case"]["name"].value_or(std::string()), "default-upper-arm");
  EXPECT_EQ(t["case"]["volume"].value_or(std::string()), "volume.mha");
  EXPECT_EQ(t["case"]["labels"].value_or(std::string()), "labels.mha");
  const auto* nodes = t["mesh"]["nodes"].as_array();
  ASSERT_NE(nodes, nullptr);
  ASSERT_EQ(nodes->size(), 3u);
  EXPECT_EQ(nodes->at(0).value_or(0), 37);
  EXPECT_EQ(nodes->at(1).value_or(0), 9);
  EXPECT_EQ(nodes->at(2).value_or(0), 28);
  EXPECT_EQ(t["mesh"]["region_min_mm"][0].value_or(0.0), -30.0);
  EXPECT_EQ(t["mesh"]["region_max_mm"][2].value_or(0.0), 45.0);
  EXPECT_EQ(t["mesh"]["fixed_faces"][0].value_or(std::string()), "z_max");
  EXPECT_EQ(t["mesh"]["fix_label"][0].value_or(0), 7);
  const auto* materials = t["materials"].as_array();
  ASSERT_NE(materials, nullptr);
  ASSERT_EQ(materials->size(), 7u);
  for (std::size_t m = 0; m < materials->size(); ++m) {
    const auto& mat = *materials->at(m).as_table();
    EXPECT_EQ(mat["label"].value_or(0), static_cast<int>(m) + 1);
    const double e = mat["youngs_modulus_kpa"].value_or(-1.0);
    const double nu = mat["poisson_ratio"].value_or(-1.0);
    EXPECT_TRUE(e > 0.0 && e <= 1e7) << m;
    EXPECT_TRUE(nu >= 0.0 && nu < 0.5) << m;
  }
  // The contrast the trainer is about: the vein is far softer than the artery.
  EXPECT_LT((*materials->at(3).as_table())["youngs_modulus_kpa"].value_or(0.0) * 100,
            (*materials->at(4).as_table())["youngs_modulus_kpa"].value_or(0.0));
  EXPECT_EQ(t["probe"]["kind"].value_or(std::string()), "linear");
  EXPECT_EQ(t["probe"]["width_mm"].value_or(0.0), 38.0);
  EXPECT_EQ(t["probe"]["depth_mm"].value_or(0.0), 40.0);
  EXPECT_EQ(t["scan"]["start_mm"][0].value_or(0.0), -2.0);
  EXPECT_EQ(t["scan"]["start_mm"][1].value_or(0.0), -12.0);
  EXPECT_EQ(t["scan"]["end_mm"][1].value_or(0.0), 12.0);
  EXPECT_EQ(t["scan"]["press_depth_mm"].value_or(0.0), 8.0);
}

// The case the build ships (target ultrasim_default_case, part of ALL).
TEST(DefaultCaseBuilt, ShippedCaseIsTheFullResolutionGrid) {
  const auto dir = std::filesystem::path(ULTRASIM_BINARY_DIR) / "cases" / "default";
  if (!std::filesystem::exists(dir / "volume.mha")) {
    GTEST_SKIP() << "build the ultrasim_default_case target first";
  }
  const auto echo = imaging::read_volume_u8(dir / "volume.mha");
  const auto labels = imaging::read_volume_u8(dir / "labels.mha");
  EXPECT_EQ(echo.size(), Eigen::Vector3i(241, 161, 181));
  EXPECT_EQ(labels.size(), echo.size());
  EXPECT_EQ(echo.spacing_mm(), Eigen::Vector3d::Constant(0.25));
  EXPECT_EQ(echo.origin_mm(), Eigen::Vector3d(-30, -20, 0));
  EXPECT_TRUE(std::filesystem::exists(dir / "case.toml"));
  EXPECT_EQ(labels.sample_nearest(Eigen::Vector3d(-8, 0, 11), 255), kVein);
  EXPECT_EQ(labels.sample_nearest(Eigen::Vector3d(6, 0, 19), 255), kArtery);
}

}  // namespace
}  // namespace ultrasim::tools
