#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "scratch_dir.hpp"
#include "ultrasim/drivers/camera/image_sequence.hpp"
#include "ultrasim/drivers/camera/v4l2_camera.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::camera {
namespace {

// A w × h colour image whose every pixel is (b, g, r).
void write_image(const std::filesystem::path& path, int w, int h, int b, int g, int r) {
  cv::Mat image(h, w, CV_8UC3, cv::Scalar(b, g, r));
  ASSERT_TRUE(cv::imwrite(path.string(), image));
}

TEST(ImageSequence, PlaysAFolderInNameOrderAsGrey) {
  testing::ScratchDir dir;
  write_image(dir / "b.png", 8, 6, 0, 0, 255);  // red
  write_image(dir / "a.png", 8, 6, 255, 255, 255);
  write_image(dir / "c.jpg", 4, 4, 0, 255, 0);  // green
  std::ofstream(dir / "notes.txt") << "not an image";
  hal::ManualClock clock(1'000);
  ImageSequenceSource source(dir.path(), clock);
  ASSERT_EQ(source.files().size(), 3u);
  hal::CameraFrame frame;
  ASSERT_TRUE(source.next_frame(frame, 0));
  EXPECT_EQ(frame.width, 8);
  EXPECT_EQ(frame.height, 6);
  EXPECT_EQ(frame.grey[0], 255);
  EXPECT_EQ(frame.sequence, 0u);
  EXPECT_EQ(frame.timestamp_us, 1'000);
  ASSERT_TRUE(source.next_frame(frame, 0));
  EXPECT_NEAR(frame.grey[0], 76, 1);  // 0.299 × 255: luminance of pure red
  ASSERT_TRUE(source.next_frame(frame, 0));
  EXPECT_EQ(frame.width, 4);
  EXPECT_NEAR(frame.grey[5], 150, 2);  // 0.587 × 255
  EXPECT_FALSE(source.next_frame(frame, 0));
  EXPECT_EQ(source.health(), hal::FrameSourceHealth::kEnded);
}

// A damaged file does not stop the sequence: it is skipped, counted and named.
TEST(ImageSequence, SkipsAFileItCannotReadAndNamesIt) {
  testing::ScratchDir dir;
  write_image(dir / "1.png", 4, 4, 10, 10, 10);
  std::ofstream(dir / "2.png") << "truncated";
  write_image(dir / "3.png", 4, 4, 20, 20, 20);
  hal::ManualClock clock;
  ImageSequenceSettings settings;
  settings.loop = true;
  ImageSequenceSource source(dir.path(), clock, settings);
  hal::CameraFrame frame;
  std::vector<int> seen;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(source.next_frame(frame, 0));
    seen.push_back(frame.grey[0]);
  }
  EXPECT_EQ(seen, (std::vector<int>{10, 20, 10, 20}));
  EXPECT_EQ(source.unreadable_files(), 2u);
  EXPECT_NE(source.status().find("2.png: cannot be read"), std::string_view::npos);
  EXPECT_EQ(source.health(), hal::FrameSourceHealth::kOk);
}

TEST(ImageSequence, RefusesAFolderWithoutImages) {
  testing::ScratchDir dir;
  hal::ManualClock clock;
  try {
    ImageSequenceSource source(dir.path(), clock);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(dir.path().string()), std::string::npos);
  }
  EXPECT_THROW(ImageSequenceSource(std::vector<std::filesystem::path>{dir / "missing.png"}, clock),
               std::invalid_argument);
}

TEST(ImageSequence, PacesFramesOnTheClock) {
  testing::ScratchDir dir;
  for (int i = 0; i < 4; ++i) write_image(dir / (std::to_string(i) + ".png"), 4, 4, 0, 0, 0);
  posix::MonotonicClock clock;
  ImageSequenceSource source(dir.path(), clock, {100.0, false});
  hal::CameraFrame frame;
  std::vector<hal::TimestampUs> stamps;
  while (source.next_frame(frame, 50'000)) stamps.push_back(frame.timestamp_us);
  ASSERT_EQ(stamps.size(), 4u);
  for (std::size_t i = 1; i < stamps.size(); ++i) EXPECT_GE(stamps[i] - stamps[i - 1], 10'000);
}

// Frames are stamped at their slots, a period apart however long each wait took; one asked for
// late comes at once and the schedule starts again from it, so the next keeps the rate instead of
// coming in a burst to catch up (an absolute schedule did that under load: 10 µs apart). The
// clock stands still but where the test moves it (the waits still sleep, a period at most).
TEST(ImageSequence, StampsFramesAtTheirSlotsAndALateOneRestartsTheSchedule) {
  testing::ScratchDir dir;
  for (int i = 0; i < 4; ++i) write_image(dir / (std::to_string(i) + ".png"), 4, 4, 0, 0, 0);
  hal::ManualClock clock(1'000'000);
  ImageSequenceSource source(dir.path(), clock, {100.0, false});
  hal::CameraFrame frame;
  std::vector<hal::TimestampUs> stamps;
  for (int i = 0; i < 4; ++i) {
    if (i == 2) clock.advance_us(45'000);  // the third frame, due at +20 ms, asked for at +45 ms
    ASSERT_TRUE(source.next_frame(frame, 50'000)) << i;
    stamps.push_back(frame.timestamp_us - 1'000'000);
  }
  EXPECT_EQ(stamps, (std::vector<hal::TimestampUs>{0, 10'000, 45'000, 55'000}));
}

// No camera plugged in: the source says so, names the device, and keeps trying without
// blocking longer than asked.
TEST(V4l2Camera, AMissingDeviceIsAFaultNotACrash) {
  posix::MonotonicClock clock;
  V4l2CameraSettings settings;
  settings.device = "/dev/video-ultrasim-missing";
  V4l2CameraSource camera(settings, clock);
  EXPECT_EQ(camera.health(), hal::FrameSourceHealth::kFault);
  EXPECT_NE(camera.status().find("/dev/video-ultrasim-missing"), std::string_view::npos);
  hal::CameraFrame frame;
  const auto start = clock.now_us();
  EXPECT_FALSE(camera.next_frame(frame, 20'000));
  EXPECT_LT(clock.now_us() - start, 500'000);
}

}  // namespace
}  // namespace ultrasim::drivers::camera
