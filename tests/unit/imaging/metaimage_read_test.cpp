// read_volume_u8 on PLUS's reference reconstruction and on hand-written headers that exercise
// the MetaIO conventions (synonyms, direction layout, .mhd + raw).

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

#include "byte_files.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {
namespace {

using testing::fnv1a64;
using testing::ScratchDir;
using testing::write_bytes;

const std::filesystem::path kPlusDir = std::filesystem::path(ULTRASIM_TEST_DATA_DIR) / "plus";

// Expected values computed independently with Python's zlib/struct on the same file.
TEST(MetaImageRead, PlusReferenceVolumeGeometry) {
  const auto volume = read_volume_u8(kPlusDir / "vtkVolumeReconstructorTestNNMEANvolumeRef.mha");
  EXPECT_EQ(volume.size(), Eigen::Vector3i(147, 106, 105));
  EXPECT_EQ(volume.spacing_mm(), Eigen::Vector3d(0.5, 0.5, 0.5));
  EXPECT_DOUBLE_EQ(volume.origin_mm().x(), -74.5217);
  EXPECT_DOUBLE_EQ(volume.origin_mm().y(), 165.573);
  EXPECT_DOUBLE_EQ(volume.origin_mm().z(), 29.072);
  EXPECT_EQ(volume.direction(), Eigen::Matrix3d::Identity());
}

TEST(MetaImageRead, PlusReferenceVolumeVoxels) {
  const auto volume = read_volume_u8(kPlusDir / "vtkVolumeReconstructorTestNNMEANvolumeRef.mha");
  const auto voxels = volume.voxels();
  ASSERT_EQ(voxels.size(), 147u * 106u * 105u);
  const std::uint64_t sum = std::accumulate(voxels.begin(), voxels.end(), std::uint64_t{0});
  const auto nonzero = std::count_if(voxels.begin(), voxels.end(), [](auto v) { return v != 0; });
  EXPECT_EQ(sum, 29029641u);
  EXPECT_EQ(nonzero, 406763);
  EXPECT_EQ(fnv1a64(voxels), 0x2286a819e22ab544ULL);
  // Index order: x fastest (i + 147·(j + 106·k)).
  EXPECT_EQ(volume.at(0, 0, 0), 0);
  EXPECT_EQ(volume.at(100, 50, 60), 5);
  EXPECT_EQ(volume.at(50, 80, 30), 244);
  EXPECT_EQ(volume.at(32, 21, 3), 155);
  EXPECT_EQ(volume.at(64, 42, 6), 242);
  EXPECT_EQ(volume.at(96, 63, 9), 245);
}

// A header as ITK writes it for a volume whose index axis i points along world +y and j along
// world -x: TransformMatrix lists the direction matrix column by column.
TEST(MetaImageRead, TransformMatrixIsColumnByColumnAsItkWritesIt) {
  ScratchDir dir;
  const std::string header =
      "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
      "CompressedData = False\nTransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 10 20 30\n"
      "ElementSpacing = 2 3 4\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
      "ElementDataFile = LOCAL\n";
  write_bytes(dir / "rot.mha", header + std::string("\x01\x02\x03\x04\x05\x06\x07\x08", 8));
  const auto volume = read_volume_u8(dir / "rot.mha");
  const Eigen::Vector3d i_step = volume.index_to_world({1, 0, 0}) - volume.origin_mm();
  const Eigen::Vector3d j_step = volume.index_to_world({0, 1, 0}) - volume.origin_mm();
  EXPECT_TRUE(i_step.isApprox(Eigen::Vector3d(0, 2, 0))) << i_step.transpose();
  EXPECT_TRUE(j_step.isApprox(Eigen::Vector3d(-3, 0, 0))) << j_step.transpose();
  EXPECT_EQ(volume.at(1, 1, 1), 8);
  EXPECT_EQ(volume.at(1, 0, 0), 2);
}

// Synonyms MetaIO accepts: ElementSize for spacing, Position for the origin, Key=Value without
// blanks, CRLF line ends, padded values, T/F booleans.
TEST(MetaImageRead, AcceptsMetaIoSynonymsAndLooseFormatting) {
  ScratchDir dir;
  const std::string header =
      "ObjectType=Image\r\nNDims = 3\r\n\r\nBinaryData = T\r\nCompressedData = F\r\n"
      "Position = 1.5 -2 +3e1\r\nElementSize = 0.25 0.5 1\r\nDimSize =   3    1      1   \r\n"
      "ElementNumberOfChannels = 1\r\nElementType = MET_UCHAR\r\nElementDataFile = LOCAL\r\n";
  write_bytes(dir / "loose.mha", header + "abc");
  const auto volume = read_volume_u8(dir / "loose.mha");
  EXPECT_EQ(volume.size(), Eigen::Vector3i(3, 1, 1));
  EXPECT_EQ(volume.spacing_mm(), Eigen::Vector3d(0.25, 0.5, 1));
  EXPECT_EQ(volume.origin_mm(), Eigen::Vector3d(1.5, -2, 30));
  EXPECT_EQ(volume.at(2, 0, 0), 'c');
}

TEST(MetaImageRead, MhdWithSeparateRawFile) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "data");
  write_bytes(dir / "data" / "v.raw", std::string("XXXX") + "\x0a\x0b\x0c\x0d");
  write_bytes(dir / "v.mhd",
              "NDims = 3\nDimSize = 2 2 1\nElementSpacing = 1 1 1\nHeaderSize = 4\n"
              "ElementType = MET_UCHAR\nElementDataFile = data/v.raw\n");
  const auto volume = read_volume_u8(dir / "v.mhd");
  EXPECT_EQ(volume.at(0, 0, 0), 0x0a);
  EXPECT_EQ(volume.at(1, 1, 0), 0x0d);
}

}  // namespace
}  // namespace ultrasim::imaging
