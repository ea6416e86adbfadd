// The kiosk driven by each recorded probe source chosen in app.toml's [probe], as a user would
// set it up: a candump log from the bring-up tool (can-replay), and camera frames of the
// probe's dodecahedron rendered by ultrasim-camera-views while the probe follows the case's
// sweep and press (camera-images). Checked against the same case's scripted run.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/input.h>
#include <png.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "evdev_records.hpp"
#include "report_json.hpp"

namespace {

namespace fs = std::filesystem;
using ultrasim::testing::json_number;
using ultrasim::testing::read_text;

int run(const std::string& command, const fs::path& log) {
  return std::system((command + " > " + log.string() + " 2>&1").c_str());
}

std::string json_string(const std::string& json, const std::string& key) {
  const std::string needle = "\"" + key + "\": \"";
  const auto at = json.find(needle);
  if (at == std::string::npos) return "<missing " + key + ">";
  const auto start = at + needle.size();
  return json.substr(start, json.find('"', start) - start);
}

class ProbeSources : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("ultrasim-sources-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const std::string kiosk =
        std::string(ULTRASIM_KIOSK_EXE) + " --headless --case " + ULTRASIM_DEFAULT_CASE + " --out ";
    // The recordings.
    demo_ok_ = run(std::string(ULTRASIM_BRINGUP_EXE) + " --write-demo " +
                       (dir_ / "demo.log").string() + " --seconds 1",
                   dir_ / "demo.txt") == 0;
    views_ok_ = run(std::string(ULTRASIM_CAMERA_VIEWS_EXE) + " --case " + ULTRASIM_DEFAULT_CASE +
                        " --out " + (dir_ / "frames").string(),
                    dir_ / "views.txt") == 0;
    // The pivot on the skin over the middle of the case's sweep: the probe rests in contact.
    std::ofstream(dir_ / "replay.toml")
        << "[probe]\nsource = \"can-replay\"\ncan_log = \"" << (dir_ / "demo.log").string()
        << "\"\npivot_mm = [-2.0, 0.0, 1.0]\n";
    std::ofstream(dir_ / "stale.toml")
        << "[probe]\nsource = \"can-replay\"\ncan_log = \"" << (dir_ / "demo.log").string()
        << "\"\nreplay_loop = false\npivot_mm = [-2.0, 0.0, 1.0]\n";
    std::ofstream(dir_ / "camera.toml") << "[probe]\nsource = \"camera-images\"\ncamera_images = \""
                                        << (dir_ / "frames").string() << "\"\n";
    replay_code_ = run(kiosk + (dir_ / "replay").string() + " --config " +
                           (dir_ / "replay.toml").string() + " --probe-seconds 2",
                       dir_ / "replay.txt");
    stale_code_ = run(kiosk + (dir_ / "stale").string() + " --config " +
                          (dir_ / "stale.toml").string() + " --probe-seconds 2",
                      dir_ / "stale.txt");
    camera_code_ = run(kiosk + (dir_ / "camera").string() + " --config " +
                           (dir_ / "camera.toml").string() + " --probe-seconds 8",
                       dir_ / "camera.txt");
    script_code_ = run(kiosk + (dir_ / "script").string(), dir_ / "script.txt");
    // The keyboard source reading evdev records from a FIFO the test holds open (a device that
    // stays plugged in): a mouse move and a wheel press.
    const fs::path fifo = dir_ / "mouse.evdev";
    ::mkfifo(fifo.c_str(), 0600);
    const int device = ::open(fifo.c_str(), O_RDWR | O_NONBLOCK);
    const auto record = [device](std::uint16_t type, std::uint16_t code, std::int32_t value) {
      return ultrasim::testing::write_input_event(device, type, code, value);
    };
    keyboard_written_ = device >= 0 && record(EV_REL, REL_X, -20) &&  // 2 mm to the left
                        record(EV_REL, REL_WHEEL, -12) &&  // 6 mm down: 1 mm into the skin
                        record(EV_SYN, SYN_REPORT, 0);
    // The trainer's mouse for the on-screen controls, on a second FIFO ([display]
    // pointer_device): from the screen's centre (over the 3D view) a drag 100 px to the left
    // and two wheel notches up.
    const fs::path pointer_fifo = dir_ / "pointer.evdev";
    ::mkfifo(pointer_fifo.c_str(), 0600);
    const int pointer = ::open(pointer_fifo.c_str(), O_RDWR | O_NONBLOCK);
    const auto pointer_record = [pointer](std::uint16_t type, std::uint16_t code,
                                          std::int32_t value) {
      return ultrasim::testing::write_input_event(pointer, type, code, value);
    };
    pointer_written_ = pointer >= 0 && pointer_record(EV_KEY, BTN_LEFT, 1) &&
                       pointer_record(EV_SYN, SYN_REPORT, 0);
    for (int i = 0; i < 5 && pointer_written_; ++i) {
      pointer_written_ =
          pointer_record(EV_REL, REL_X, -20) && pointer_record(EV_SYN, SYN_REPORT, 0);
    }
    pointer_written_ = pointer_written_ && pointer_record(EV_KEY, BTN_LEFT, 0) &&
                       pointer_record(EV_SYN, SYN_REPORT, 0) &&
                       pointer_record(EV_REL, REL_WHEEL, 2) &&
                       pointer_record(EV_SYN, SYN_REPORT, 0);
    std::ofstream(dir_ / "keyboard.toml")
        << "[display]\npointer_device = \"" << pointer_fifo.string() << "\"\n"
        << "[probe]\nsource = \"keyboard\"\nkeyboard_device = \"" << fifo.string() << "\"\n";
    keyboard_code_ = run(kiosk + (dir_ / "keyboard").string() + " --config " +
                             (dir_ / "keyboard.toml").string() + " --probe-seconds 1",
                         dir_ / "keyboard.txt");
    if (device >= 0) ::close(device);
    if (pointer >= 0) ::close(pointer);
    // A camera that is not plugged in.
    std::ofstream(dir_ / "unplugged.toml")
        << "[probe]\nsource = \"camera\"\ncamera_device = \"/dev/video-ultrasim-none\"\n";
    unplugged_code_ = run(kiosk + (dir_ / "unplugged").string() + " --config " +
                              (dir_ / "unplugged.toml").string() + " --probe-seconds 1",
                          dir_ / "unplugged.txt");
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string report(const char* run_name) {
    return read_text(dir_ / run_name / "report.json");
  }

  static inline fs::path dir_;
  static inline bool demo_ok_ = false, views_ok_ = false;
  static inline int replay_code_ = -1, stale_code_ = -1, camera_code_ = -1, script_code_ = -1,
                    keyboard_code_ = -1, unplugged_code_ = -1;
  static inline bool keyboard_written_ = false, pointer_written_ = false;
};

TEST_F(ProbeSources, ACanLogReplayedMovesTheProbe) {
  ASSERT_TRUE(demo_ok_) << read_text(dir_ / "demo.txt");
  ASSERT_EQ(replay_code_, 0) << read_text(dir_ / "replay.txt");
  const std::string json = report("replay");
  EXPECT_EQ(json_string(json, "source"), "can-replay");
  EXPECT_EQ(json_number(json, "frames"), 121);
  EXPECT_EQ(json_number(json, "poses_rejected"), 0);
  EXPECT_EQ(json_number(json, "status_frames"), 0);
  EXPECT_GT(json_number(json, "frames_in_contact"), 100);
  EXPECT_TRUE(fs::exists(dir_ / "replay" / "screen-probe-end.png"));
  // Every frame took a new pose: each has a probe-to-photon time (not judged here: speed is
  // the benchmarks').
  const auto latency = json.find("\"probe_to_photon\"");
  ASSERT_NE(latency, std::string::npos);
  EXPECT_EQ(json_number(json, "count", latency), 121);
  EXPECT_GT(json_number(json, "p50_us", latency), 0);
}

// Reddish pixels (the warning colour) along the foot of the B-scan panel of a 1280 × 720 screen.
int warning_pixels(const fs::path& png) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, png.c_str())) return -1;
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> rgb(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr)) return -1;
  int count = 0;
  for (std::uint32_t y = image.height - 40; y < image.height; ++y) {
    for (std::uint32_t x = image.width / 2; x < image.width; ++x) {
      const std::uint8_t* p = &rgb[(y * image.width + x) * 3];
      count += p[0] > 180 && p[1] < 120 && p[2] < 120;
    }
  }
  return count;
}

// The log runs out after a second: the pose goes stale, the last good one is held, and the
// screen says why.
TEST_F(ProbeSources, AStaleProbeIsHeldAndShownOnScreen) {
  ASSERT_EQ(stale_code_, 0) << read_text(dir_ / "stale.txt");
  const std::string json = report("stale");
  EXPECT_GT(json_number(json, "status_frames"), 50);
  EXPECT_EQ(json_string(json, "last_status").rfind("replay: no orientation for ", 0), 0u);
  EXPECT_EQ(json_number(json, "diverged_frames"), 0);
  EXPECT_GT(warning_pixels(dir_ / "stale" / "screen-probe-end.png"), 100);
  EXPECT_EQ(warning_pixels(dir_ / "replay" / "screen-probe-end.png"), 0);
}

// The camera tracks the dodecahedron through the sweep and the press: the tissue is pressed as
// hard as when the script moves the probe directly.
TEST_F(ProbeSources, CameraFramesTrackTheScriptedPress) {
  ASSERT_TRUE(views_ok_) << read_text(dir_ / "views.txt");
  ASSERT_EQ(camera_code_, 0) << read_text(dir_ / "camera.txt");
  ASSERT_EQ(script_code_, 0) << read_text(dir_ / "script.txt");
  const std::string camera = report("camera");
  const std::string script = report("script");
  EXPECT_EQ(json_string(camera, "source"), "camera-images");
  const double frames = json_number(camera, "frames");
  EXPECT_EQ(frames, 481);
  EXPECT_LE(json_number(camera, "poses_rejected"), 2);
  EXPECT_EQ(json_number(camera, "status_frames"), 0);
  // The probe hovers for the first 0.75 s, then stays on the skin (measured: 436 of 481).
  EXPECT_GT(json_number(camera, "frames_in_contact"), 0.85 * frames);
  const double tracked_force = json_number(camera, "max_contact_force_n");
  const double scripted_force = json_number(script, "max_contact_force_n");
  EXPECT_NEAR(tracked_force, scripted_force, 0.05 * scripted_force);  // measured: 0.7 % apart
}

// The keyboard source in the app: the mouse moves the probe from above the skin onto it. (A
// device going away is keyboard_probe_test's.)
TEST_F(ProbeSources, TheKeyboardSourceMovesTheProbe) {
  ASSERT_TRUE(keyboard_written_);
  ASSERT_EQ(keyboard_code_, 0) << read_text(dir_ / "keyboard.txt");
  const std::string json = report("keyboard");
  EXPECT_EQ(json_string(json, "source"), "keyboard");
  EXPECT_EQ(json_number(json, "status_frames"), 0);
  EXPECT_EQ(json_number(json, "poses_rejected"), 0);
  EXPECT_GT(json_number(json, "frames_in_contact"), 0.9 * json_number(json, "frames"));
}

// The trainer's mouse (an evdev node named by [display] pointer_device) works the on-screen
// controls: its drag over the 3D view turned it, its wheel zoomed in.
TEST_F(ProbeSources, ThePointerDeviceOrbitsAndZoomsTheView) {
  ASSERT_TRUE(pointer_written_);
  ASSERT_EQ(keyboard_code_, 0) << read_text(dir_ / "keyboard.txt");
  const std::string json = report("keyboard");
  const std::size_t end = json.find("\"marker\": \"probe-end\"");
  ASSERT_NE(end, std::string::npos);
  // 100 px of a 692 px wide view at 180° a width: 26°, the view turned to the right.
  EXPECT_NEAR(json_number(json, "view_azimuth_offset_deg", end), 100.0 * 180.0 / 692.0, 1.0);
  EXPECT_NEAR(json_number(json, "view_zoom", end), 1.15 * 1.15, 1e-3);
}

// No camera: the kiosk runs on, says so on screen and in the report, and never moves the probe.
TEST_F(ProbeSources, AMissingCameraIsReportedNotFatal) {
  ASSERT_EQ(unplugged_code_, 0) << read_text(dir_ / "unplugged.txt");
  const std::string json = report("unplugged");
  EXPECT_EQ(json_string(json, "source"), "camera");
  const double frames = json_number(json, "frames");
  EXPECT_EQ(json_number(json, "status_frames"), frames);
  EXPECT_EQ(json_number(json, "frames_in_contact"), 0);
  EXPECT_NE(json_string(json, "last_status").find("/dev/video-ultrasim-none: cannot open"),
            std::string::npos);
  EXPECT_GT(warning_pixels(dir_ / "unplugged" / "screen-probe-end.png"), 100);
}

}  // namespace
