// read_tracked_sequence on three real PLUS recordings. Expected values were read from the files
// with Python's zlib, independently of our reader.

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <span>

#include "byte_files.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {
namespace {

using testing::fnv1a64;

const std::filesystem::path kPlusDir = std::filesystem::path(ULTRASIM_TEST_DATA_DIR) / "plus";

std::span<const std::uint8_t> frame_pixels(const TrackedSequence& seq, std::size_t f) {
  const std::size_t n = static_cast<std::size_t>(seq.width_px) * seq.height_px;
  return std::span<const std::uint8_t>(seq.pixels).subspan(f * n, n);
}

void expect_timestamps_increase(const TrackedSequence& seq) {
  for (std::size_t f = 1; f < seq.frames.size(); ++f) {
    EXPECT_GT(seq.frames[f].timestamp_s, seq.frames[f - 1].timestamp_s) << "frame " << f;
  }
}

TEST(TrackedSequence, SpinePhantom) {
  const auto seq = read_tracked_sequence(kPlusDir / "SpinePhantomFreehand.igs.mha");
  EXPECT_EQ(seq.width_px, 820);
  EXPECT_EQ(seq.height_px, 616);
  ASSERT_EQ(seq.frames.size(), 21u);
  ASSERT_EQ(seq.pixels.size(), 820u * 616u * 21u);

  const auto& first = seq.frames.front();
  EXPECT_DOUBLE_EQ(first.timestamp_s, 215.102186);
  EXPECT_DOUBLE_EQ(seq.frames.back().timestamp_s, 216.947186);
  expect_timestamps_increase(seq);
  ASSERT_EQ(first.transforms.count("ProbeToTracker"), 1u);
  const Eigen::Matrix4d& probe = first.transforms.at("ProbeToTracker");
  // "0.231245 0.951424 -0.203269 172.641 -0.127436 ... 0 0 0 1", row-major.
  EXPECT_DOUBLE_EQ(probe(0, 0), 0.231245);
  EXPECT_DOUBLE_EQ(probe(0, 1), 0.951424);
  EXPECT_DOUBLE_EQ(probe(0, 3), 172.641);
  EXPECT_DOUBLE_EQ(probe(1, 0), -0.127436);
  EXPECT_DOUBLE_EQ(probe(2, 3), -22.0262);
  EXPECT_EQ(probe.row(3), Eigen::RowVector4d(0, 0, 0, 1));
  EXPECT_EQ(first.transforms.size(), 3u);  // ProbeToTracker, ReferenceToTracker, StylusToTracker
  for (const auto& frame : seq.frames) {
    EXPECT_TRUE(frame.image_ok);
    for (const auto& [name, ok] : frame.transform_ok) EXPECT_TRUE(ok) << name;
  }

  EXPECT_EQ(fnv1a64(frame_pixels(seq, 0)), 0x46147d68818b8105ULL);
  const auto last = frame_pixels(seq, 20);
  EXPECT_EQ(std::accumulate(last.begin(), last.end(), std::uint64_t{0}), 17810681u);

  EXPECT_EQ(seq.header.at("UltrasoundImageOrientation"), "MFA");
  EXPECT_EQ(seq.header.at("CompressedDataSize"), "3466024");  // padding blanks trimmed
  for (const auto& [key, value] : seq.header) EXPECT_FALSE(key.starts_with("Seq_Frame")) << key;
}

TEST(TrackedSequence, NwirePhantomStylusIsInvalid) {
  const auto seq = read_tracked_sequence(kPlusDir / "NwirePhantomFreehand.igs.mha");
  ASSERT_EQ(seq.frames.size(), 97u);
  expect_timestamps_increase(seq);
  const auto& first = seq.frames.front();
  EXPECT_DOUBLE_EQ(first.transforms.at("ProbeToTracker")(0, 3), -190.886);
  EXPECT_DOUBLE_EQ(first.transforms.at("ProbeToTracker")(2, 3), -1949.07);
  // Written as "-8.43482e-005", with a trailing blank after the last number.
  EXPECT_DOUBLE_EQ(first.transforms.at("StylusToTracker")(0, 1), -8.43482e-5);
  for (const auto& frame : seq.frames) {
    EXPECT_FALSE(frame.transform_ok.at("StylusToTracker"));
    EXPECT_TRUE(frame.transform_ok.at("ProbeToTracker"));
    EXPECT_TRUE(frame.transform_ok.at("ReferenceToTracker"));
    EXPECT_TRUE(frame.image_ok);
  }
  EXPECT_EQ(fnv1a64(frame_pixels(seq, 0)), 0x7727455a43aa72c7ULL);
  const auto last = frame_pixels(seq, 96);
  EXPECT_EQ(std::accumulate(last.begin(), last.end(), std::uint64_t{0}), 1311665u);
}

TEST(TrackedSequence, WaterTankPaddedHeaderAndExtraFields) {
  const auto seq = read_tracked_sequence(kPlusDir / "WaterTankBottomTranslationCombined.igs.mha");
  ASSERT_EQ(seq.frames.size(), 201u);
  EXPECT_EQ(seq.width_px, 820);
  EXPECT_EQ(seq.height_px, 616);
  expect_timestamps_increase(seq);
  const auto& first = seq.frames.front();
  EXPECT_DOUBLE_EQ(first.timestamp_s, 7417.7313);
  EXPECT_DOUBLE_EQ(seq.frames.back().timestamp_s, 7435.148643);
  EXPECT_DOUBLE_EQ(first.transforms.at("ProbeToTracker")(0, 3), 199.132);
  EXPECT_EQ(first.transforms.at("ProbeToTracker")(3, 0), 0.0);  // written "-0"
  EXPECT_EQ(first.other_fields.at("FrameNumber"), "1449");
  EXPECT_EQ(first.other_fields.at("UnfilteredTimestamp"), "7417.730000");
  EXPECT_EQ(seq.frames[1].other_fields.at("FrameNumber"), "1450");
  EXPECT_EQ(first.other_fields.count("Timestamp"), 0u);  // parsed, not kept twice
  EXPECT_EQ(seq.header.at("DimSize"), "820 616                    201");
  EXPECT_EQ(fnv1a64(frame_pixels(seq, 0)), 0xf5bc2349aee705e9ULL);
  const auto last = frame_pixels(seq, 200);
  EXPECT_EQ(std::accumulate(last.begin(), last.end(), std::uint64_t{0}), 235047u);
}

TEST(TrackedSequence, ReferenceVolumeIsNotASequence) {
  // It carries one stray Seq_Frame0000_ImageStatus but no timestamps: read as a sequence it
  // must fail cleanly, naming the missing field.
  try {
    (void)read_tracked_sequence(kPlusDir / "vtkVolumeReconstructorTestNNMEANvolumeRef.mha");
    FAIL() << "expected MetaImageError";
  } catch (const MetaImageError& e) {
    EXPECT_NE(std::string(e.what()).find("Seq_Frame0000_Timestamp: required field missing"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ultrasim::imaging
