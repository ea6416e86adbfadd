// Malformed MetaImage files: each must throw MetaImageError whose one-line message names the
// file, the header line and the field at fault.

#include <gtest/gtest.h>

#include <string>

#include "byte_files.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {
namespace {

using testing::read_bytes;
using testing::ScratchDir;
using testing::write_bytes;

// The message of the MetaImageError that reading `path` throws, or "" when it reads fine.
std::string volume_error(const std::filesystem::path& path) {
  try {
    (void)read_volume_u8(path);
  } catch (const MetaImageError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << "message must be one line: " << what;
    return what;
  }
  return "";
}

std::string sequence_error(const std::filesystem::path& path) {
  try {
    (void)read_tracked_sequence(path);
  } catch (const MetaImageError& e) {
    return e.what();
  }
  return "";
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// A valid 4×4×4 file as our writer makes it; the header's lines are, from 1:
// ObjectType NDims BinaryData BinaryDataByteOrderMSB CompressedData [CompressedDataSize]
// TransformMatrix Offset CenterOfRotation AnatomicalOrientation ElementSpacing DimSize ElementType
// ElementDataFile.
std::string valid_file(const ScratchDir& dir, bool compress) {
  Volume<std::uint8_t> volume({4, 4, 4}, {1, 1, 1}, {0, 0, 0});
  for (std::size_t n = 0; n < volume.voxel_count(); ++n)
    volume.voxels()[n] = static_cast<std::uint8_t>(n * 7);
  write_volume(dir / "valid.mha", volume, compress);
  return read_bytes(dir / "valid.mha");
}

#define EXPECT_MESSAGE_HAS(message, part)            \
  EXPECT_NE((message).find(part), std::string::npos) \
      << "'" << (message) << "' lacks '" << (part) << "'"

TEST(MetaImageError, MissingFileNamesTheFile) {
  ScratchDir dir;
  const std::string message = volume_error(dir / "absent.mha");
  EXPECT_MESSAGE_HAS(message, "absent.mha");
  EXPECT_MESSAGE_HAS(message, "no such file");
}

TEST(MetaImageError, TruncatedRawData) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  write_bytes(dir / "short.mha", bytes.substr(0, bytes.size() - 10));
  const std::string message = volume_error(dir / "short.mha");
  EXPECT_MESSAGE_HAS(message, "short.mha:13: ElementDataFile: truncated");
  EXPECT_MESSAGE_HAS(message, "54 bytes");
}

TEST(MetaImageError, TruncatedCompressedDataAgainstCompressedDataSize) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, true);
  write_bytes(dir / "cut.mha", bytes.substr(0, bytes.size() - 5));
  EXPECT_MESSAGE_HAS(volume_error(dir / "cut.mha"), "cut.mha:6: CompressedDataSize: truncated");
}

TEST(MetaImageError, TruncatedCompressedDataWithoutCompressedDataSize) {
  ScratchDir dir;
  std::string bytes = valid_file(dir, true);
  const auto size_line = bytes.find("CompressedDataSize");
  bytes.erase(size_line, bytes.find('\n', size_line) + 1 - size_line);
  write_bytes(dir / "cut.mha", bytes.substr(0, bytes.size() - 5));
  const std::string message = volume_error(dir / "cut.mha");
  EXPECT_MESSAGE_HAS(message, "cut.mha:13: ElementDataFile: truncated zlib data");
}

TEST(MetaImageError, WrongDecompressedSize) {
  ScratchDir dir;
  // The data holds 64 voxels; a header claiming 80 or 48 must not be believed.
  const std::string bytes = valid_file(dir, true);
  write_bytes(dir / "big.mha", replace(bytes, "DimSize = 4 4 4", "DimSize = 4 4 5"));
  const std::string too_few = volume_error(dir / "big.mha");
  EXPECT_MESSAGE_HAS(too_few, "big.mha:14: ElementDataFile: zlib data inflates to 64 bytes");
  EXPECT_MESSAGE_HAS(too_few, "DimSize 4 4 5 needs 80");
  write_bytes(dir / "small.mha", replace(bytes, "DimSize = 4 4 4", "DimSize = 4 4 3"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "small.mha"),
                     "small.mha:14: ElementDataFile: zlib data inflates to more than 48");
}

TEST(MetaImageError, CorruptZlibStream) {
  ScratchDir dir;
  std::string bytes = valid_file(dir, true);
  const auto data = bytes.find("LOCAL\n") + 6;
  bytes[data] = '\x00';  // zlib header byte: not a valid stream any more
  bytes[data + 1] = '\x00';
  write_bytes(dir / "bad.mha", bytes);
  EXPECT_MESSAGE_HAS(volume_error(dir / "bad.mha"),
                     "bad.mha:14: ElementDataFile: corrupt zlib data");
}

TEST(MetaImageError, BadDimSize) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  for (const std::string dims : {"4 x 4", "4 0 4", "4 4", "4 4 4 4", "-4 4 4", "4.5 4 4", ""}) {
    write_bytes(dir / "dims.mha", replace(bytes, "DimSize = 4 4 4", "DimSize = " + dims));
    const std::string message = volume_error(dir / "dims.mha");
    EXPECT_MESSAGE_HAS(message, "dims.mha:11: DimSize: expected 3");
    EXPECT_MESSAGE_HAS(message, "'" + dims + "'");
  }
}

TEST(MetaImageError, UnsupportedElementTypeIsNamed) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  write_bytes(dir / "float.mha", replace(bytes, "MET_UCHAR", "MET_FLOAT"));
  const std::string message = volume_error(dir / "float.mha");
  EXPECT_MESSAGE_HAS(message, "float.mha:12: ElementType: unsupported element type 'MET_FLOAT'");
}

TEST(MetaImageError, NonNumericFields) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  write_bytes(dir / "s.mha", replace(bytes, "ElementSpacing = 1 1 1", "ElementSpacing = 1 one 1"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "s.mha"),
                     "s.mha:10: ElementSpacing: expected 3 numbers, got '1 one 1'");
  write_bytes(dir / "z.mha", replace(bytes, "ElementSpacing = 1 1 1", "ElementSpacing = 1 0 1"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "z.mha"), "z.mha:10: ElementSpacing: expected 3 positive");
  write_bytes(dir / "o.mha", replace(bytes, "Offset = 0 0 0", "Offset = 0 0 nan"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "o.mha"), "o.mha:7: Offset: expected 3 numbers");
  write_bytes(dir / "t.mha",
              replace(bytes, "TransformMatrix = 1 0 0 0 1 0 0 0 1", "TransformMatrix = 1 0 0"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "t.mha"), "t.mha:6: TransformMatrix: expected 9 numbers");
  write_bytes(dir / "d.mha", replace(bytes, "TransformMatrix = 1 0 0 0 1 0 0 0 1",
                                     "TransformMatrix = 1 0 0 1 0 0 0 0 1"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "d.mha"), "d.mha:6: TransformMatrix: singular");
  write_bytes(dir / "c.mha", replace(bytes, "CompressedData = False", "CompressedData = maybe"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "c.mha"),
                     "c.mha:5: CompressedData: expected True or False");
}

TEST(MetaImageError, MissingRequiredFields) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  for (const std::string field : {"NDims", "DimSize", "ElementType"}) {
    std::string text = bytes;
    const auto at = text.find(field + " = ");
    text.erase(at, text.find('\n', at) + 1 - at);
    write_bytes(dir / "m.mha", text);
    // The header now ends on line 12; the message points there.
    EXPECT_MESSAGE_HAS(volume_error(dir / "m.mha"),
                       "m.mha:12: " + field + ": required field missing");
  }
}

TEST(MetaImageError, UnsupportedShapes) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  write_bytes(dir / "n.mha", replace(bytes, "NDims = 3", "NDims = 2"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "n.mha"), "n.mha:2: NDims: expected 3");
  write_bytes(dir / "ch.mha",
              replace(bytes, "ElementType", "ElementNumberOfChannels = 3\nElementType"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "ch.mha"),
                     "ch.mha:12: ElementNumberOfChannels: expected 1");
  write_bytes(dir / "a.mha", replace(bytes, "BinaryData = True", "BinaryData = False"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "a.mha"), "a.mha:3: BinaryData: ASCII");
  write_bytes(dir / "l.mha", replace(bytes, "ElementDataFile = LOCAL", "ElementDataFile = LIST"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "l.mha"), "l.mha:13: ElementDataFile: only LOCAL");
}

TEST(MetaImageError, MalformedHeaderLines) {
  ScratchDir dir;
  const std::string bytes = valid_file(dir, false);
  write_bytes(dir / "g.mha", replace(bytes, "CenterOfRotation = 0 0 0", "CenterOfRotation 0 0 0"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "g.mha"), "g.mha:8: header: expected 'Key = Value'");
  write_bytes(dir / "r.mha", replace(bytes, "CenterOfRotation = 0 0 0", "NDims = 3"));
  EXPECT_MESSAGE_HAS(volume_error(dir / "r.mha"), "r.mha:8: NDims: repeated (first on line 2)");
  write_bytes(dir / "e.mha", "NDims = 3\nDimSize = 1 1 1\n");
  EXPECT_MESSAGE_HAS(volume_error(dir / "e.mha"), "e.mha:2: ElementDataFile: header ends without");
  write_bytes(dir / "empty.mha", "");
  EXPECT_MESSAGE_HAS(volume_error(dir / "empty.mha"), "empty.mha");
}

TEST(MetaImageError, MissingRawDataFile) {
  ScratchDir dir;
  write_bytes(dir / "v.mhd",
              "NDims = 3\nDimSize = 2 2 1\nElementType = MET_UCHAR\nElementDataFile = v.raw\n");
  const std::string message = volume_error(dir / "v.mhd");
  EXPECT_MESSAGE_HAS(message, "v.mhd:4: ElementDataFile: data file");
  EXPECT_MESSAGE_HAS(message, "v.raw");
}

const std::string kSequenceHeader =
    "ObjectType = Image\nNDims = 3\nBinaryData = True\nCompressedData = False\n"
    "DimSize = 2 1 2\nElementType = MET_UCHAR\n"
    "Seq_Frame0000_ProbeToTrackerTransform = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n"
    "Seq_Frame0000_Timestamp = 1.5\n"
    "Seq_Frame0001_ProbeToTrackerTransform = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n"
    "Seq_Frame0001_Timestamp = 1.6\n"
    "ElementDataFile = LOCAL\n";

TEST(MetaImageError, TrackedSequenceFields) {
  ScratchDir dir;
  write_bytes(dir / "ok.igs.mha", kSequenceHeader + "abcd");
  EXPECT_EQ(sequence_error(dir / "ok.igs.mha"), "");

  write_bytes(dir / "m.igs.mha", replace(kSequenceHeader, "0 0 0 1\nSeq_Frame0001_Timestamp",
                                         "0 0 1\nSeq_Frame0001_Timestamp") +
                                     "abcd");
  EXPECT_MESSAGE_HAS(sequence_error(dir / "m.igs.mha"),
                     "m.igs.mha:9: Seq_Frame0001_ProbeToTrackerTransform: expected 16 numbers");

  write_bytes(dir / "t.igs.mha",
              replace(kSequenceHeader, "Timestamp = 1.6", "Timestamp = soon") + "abcd");
  EXPECT_MESSAGE_HAS(sequence_error(dir / "t.igs.mha"),
                     "t.igs.mha:10: Seq_Frame0001_Timestamp: expected 1 number");

  write_bytes(
      dir / "f.igs.mha",
      replace(kSequenceHeader, "Seq_Frame0001_Timestamp", "Seq_Frame0002_Timestamp") + "abcd");
  EXPECT_MESSAGE_HAS(sequence_error(dir / "f.igs.mha"),
                     "f.igs.mha:10: Seq_Frame0002_Timestamp: frame 2 beyond the 2 frames");

  write_bytes(dir / "n.igs.mha",
              replace(kSequenceHeader, "Seq_Frame0001_Timestamp = 1.6\n", "") + "abcd");
  EXPECT_MESSAGE_HAS(sequence_error(dir / "n.igs.mha"),
                     "n.igs.mha:10: Seq_Frame0001_Timestamp: required field missing");

  write_bytes(dir / "p.igs.mha", kSequenceHeader + "abc");
  EXPECT_MESSAGE_HAS(sequence_error(dir / "p.igs.mha"), "p.igs.mha:11: ElementDataFile: truncated");
}

}  // namespace
}  // namespace ultrasim::imaging
