// write_volume: bit-exact round trips (compressed and raw), deterministic bytes, and a header
// that ITK/3D Slicer read the same way.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <random>

#include "byte_files.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {
namespace {

using testing::read_bytes;
using testing::ScratchDir;

// Odd sizes and spacings, a rotated frame and random voxels: nothing lines up by accident.
Volume<std::uint8_t> random_volume(std::uint32_t seed) {
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-1.1, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  Volume<std::uint8_t> volume({37, 23, 19}, {0.3, 0.45, 1.2}, {-5.5, 3.25, 100.125}, rotation);
  std::mt19937 engine(seed);  // the engine's sequence is fixed by the standard
  for (auto& v : volume.voxels()) v = static_cast<std::uint8_t>(engine() >> 24);
  return volume;
}

void expect_same_volume(const Volume<std::uint8_t>& a, const Volume<std::uint8_t>& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.spacing_mm(), b.spacing_mm());  // bit-exact: shortest round-trip text
  EXPECT_EQ(a.origin_mm(), b.origin_mm());
  EXPECT_EQ(a.direction(), b.direction());
  ASSERT_EQ(a.voxel_count(), b.voxel_count());
  EXPECT_TRUE(std::equal(a.voxels().begin(), a.voxels().end(), b.voxels().begin()));
}

TEST(MetaImageWrite, RoundTripCompressedIsBitExact) {
  ScratchDir dir;
  const auto volume = random_volume(1);
  write_volume(dir / "v.mha", volume, true);
  expect_same_volume(volume, read_volume_u8(dir / "v.mha"));
}

TEST(MetaImageWrite, RoundTripRawIsBitExact) {
  ScratchDir dir;
  const auto volume = random_volume(2);
  write_volume(dir / "v.mha", volume, false);
  const std::string bytes = read_bytes(dir / "v.mha");
  EXPECT_NE(bytes.find("CompressedData = False\n"), std::string::npos);
  EXPECT_EQ(bytes.find("CompressedDataSize"), std::string::npos);
  expect_same_volume(volume, read_volume_u8(dir / "v.mha"));
}

TEST(MetaImageWrite, SameVolumeGivesSameBytes) {
  ScratchDir dir;
  write_volume(dir / "a.mha", random_volume(3));
  write_volume(dir / "b.mha", random_volume(3));
  const std::string a = read_bytes(dir / "a.mha");
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a, read_bytes(dir / "b.mha"));
  EXPECT_FALSE(std::filesystem::exists(dir / "a.mha.partial"));
}

TEST(MetaImageWrite, HeaderListsTheAgreedFieldsInOrder) {
  ScratchDir dir;
  // Index axis i along world +y, j along world -x (a 90° turn about z).
  Eigen::Matrix3d direction;
  direction << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  Volume<std::uint8_t> volume({4, 3, 2}, {0.25, 0.5, 2}, {-30, 0.1, 45}, direction);
  std::fill(volume.voxels().begin(), volume.voxels().end(), 7);
  write_volume(dir / "h.mha", volume);
  const std::string bytes = read_bytes(dir / "h.mha");
  const auto end = bytes.find("ElementDataFile = LOCAL\n");
  ASSERT_NE(end, std::string::npos);
  const std::string header = bytes.substr(0, end);
  const std::string size = header.substr(header.find("CompressedDataSize = "));
  const std::string expected_tail =
      "TransformMatrix = 0 1 0 -1 0 0 0 0 1\n"
      "Offset = -30 0.1 45\n"
      "CenterOfRotation = 0 0 0\n"
      "AnatomicalOrientation = RAI\n"
      "ElementSpacing = 0.25 0.5 2\n"
      "DimSize = 4 3 2\n"
      "ElementType = MET_UCHAR\n";
  EXPECT_EQ(header.substr(0, header.find("CompressedDataSize")),
            "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
            "CompressedData = True\n");
  EXPECT_EQ(header.substr(header.find("TransformMatrix")), expected_tail);
  const auto payload_size = bytes.size() - end - std::string("ElementDataFile = LOCAL\n").size();
  EXPECT_EQ(size.substr(0, size.find('\n')),
            "CompressedDataSize = " + std::to_string(payload_size));
  expect_same_volume(volume, read_volume_u8(dir / "h.mha"));
}

TEST(MetaImageWrite, ReplacesAnExistingFile) {
  ScratchDir dir;
  write_volume(dir / "v.mha", random_volume(4));
  const auto second = random_volume(5);
  write_volume(dir / "v.mha", second);
  expect_same_volume(second, read_volume_u8(dir / "v.mha"));
}

TEST(MetaImageWrite, UnwritableFolderThrows) {
  ScratchDir dir;
  const auto path = dir / "no_such_folder" / "v.mha";
  try {
    write_volume(path, random_volume(6));
    FAIL() << "expected MetaImageError";
  } catch (const MetaImageError& e) {
    EXPECT_NE(std::string(e.what()).find("v.mha"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ultrasim::imaging
