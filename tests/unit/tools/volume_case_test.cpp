#include "ultrasim/tools/make_case/volume_case.hpp"

#include <gtest/gtest.h>

#include "scratch_dir.hpp"
#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::tools {
namespace {

const char* kPlusVolume =
    ULTRASIM_TEST_DATA_DIR "/plus/vtkVolumeReconstructorTestNNMEANvolumeRef.mha";

TEST(VolumeCase, PlusSpinePhantomRegionSitsInsideTheSweptData) {
  const auto volume = imaging::read_volume_u8(kPlusVolume);
  const VolumeCase c = make_volume_case(volume, VolumeCaseSettings{});
  ASSERT_TRUE(c.settings.mesh.region_min_mm && c.settings.mesh.region_max_mm);
  const auto& lo = *c.settings.mesh.region_min_mm;
  const auto& hi = *c.settings.mesh.region_max_mm;
  // Inside the volume, below its ragged top edge (the data starts 1–4 mm down), and thick
  // enough to image 3 cm deep.
  for (int a = 0; a < 3; ++a) {
    EXPECT_GE(lo[a], volume.world_min_mm()[a]);
    EXPECT_LE(hi[a], volume.world_max_mm()[a]);
    EXPECT_LT(lo[a], hi[a]);
  }
  EXPECT_GT(lo[2], volume.world_min_mm().z() + 1.0);
  EXPECT_LT(lo[2], volume.world_min_mm().z() + 8.0);
  EXPECT_GT(hi[2] - lo[2], 30.0);
  // Most of the probe's footprint on the top face holds data.
  int filled = 0, total = 0;
  const auto& start = c.settings.scan.start_mm;
  for (double x = -c.settings.probe.width_mm / 2; x <= c.settings.probe.width_mm / 2; x += 0.5) {
    ++total;
    filled += volume.sample_nearest({start[0] + x, start[1], lo[2] + 0.5}, 0) > 0;
  }
  EXPECT_GT(filled, 0.8 * total);
  EXPECT_EQ(c.settings.materials.size(), 1u);
  EXPECT_EQ(c.labels.size(), volume.size());
}

TEST(VolumeCase, WrittenCaseLoadsBack) {
  const testing::ScratchDir dir;
  const auto volume = imaging::read_volume_u8(kPlusVolume);
  const VolumeCase c = make_volume_case(volume, VolumeCaseSettings{});
  write_volume_case(dir.path(), volume, c);
  const config::CaseSettings loaded = config::load_case_settings(dir.path());
  EXPECT_EQ(loaded.mesh.nodes, c.settings.mesh.nodes);
  EXPECT_EQ(loaded.scan.start_mm, c.settings.scan.start_mm);
  EXPECT_EQ(imaging::read_volume_u8(loaded.labels_path).voxels()[123], 3);
}

TEST(VolumeCase, AnEmptyVolumeIsRefused) {
  const imaging::Volume<std::uint8_t> empty({10, 10, 10}, {1, 1, 1}, {0, 0, 0});
  EXPECT_THROW(make_volume_case(empty, VolumeCaseSettings{}), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::tools
