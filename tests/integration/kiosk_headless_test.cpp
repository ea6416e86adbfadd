// Runs `ultrasim-kiosk --headless` on the default case once and checks its report and images:
// the run is sane, the probe lifted shows no image, and under pressure the vein collapses while
// the artery stays open — measured on the B-scan PNGs, as a trainee would see them.

#include <gtest/gtest.h>
#include <png.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "report_json.hpp"
#include "ultrasim/render/png_writer.hpp"

namespace {

namespace fs = std::filesystem;
using ultrasim::testing::json_number;
using ultrasim::testing::read_text;

struct GreyImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
  int at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
};

GreyImage read_grey_png(const fs::path& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    ADD_FAILURE() << path << ": " << image.message;
    return {};
  }
  image.format = PNG_FORMAT_GRAY;
  GreyImage out{static_cast<int>(image.width), static_cast<int>(image.height), {}};
  out.pixels.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out.pixels.data(), 0, nullptr)) {
    ADD_FAILURE() << path << ": " << image.message;
  }
  return out;
}

// Dark area (mm²) inside a window of the B-scan given in probe-plane mm (lateral x from the
// image centre, depth z from the face), after a 9×9 box blur so speckle in the hypoechoic fat does
// not count as lumen. The default probe images 38 mm × 40 mm.
double dark_area_mm2(const GreyImage& img, double x0, double x1, double z0, double z1) {
  const double width_mm = 38.0, depth_mm = 40.0;
  const double px_w = width_mm / img.width, px_h = depth_mm / img.height;
  int dark = 0;
  for (int y = 0; y < img.height; ++y) {
    const double z = (y + 0.5) * px_h;
    if (z < z0 || z > z1) continue;
    for (int x = 0; x < img.width; ++x) {
      const double lateral = (x + 0.5) * px_w - width_mm / 2;
      if (lateral < x0 || lateral > x1) continue;
      int sum = 0, n = 0;
      for (int dy = -4; dy <= 4; ++dy)
        for (int dx = -4; dx <= 4; ++dx) {
          const int yy = y + dy, xx = x + dx;
          if (yy < 0 || xx < 0 || yy >= img.height || xx >= img.width) continue;
          sum += img.at(xx, yy);
          ++n;
        }
      dark += sum < 15 * n;
    }
  }
  return dark * px_w * px_h;
}

// The text field `key` a saved PNG records (render::write_png_grey's PngText), or "<missing>".
std::string png_text_field(const fs::path& png, const std::string& key) {
  for (const auto& t : ultrasim::render::read_png_text(png)) {
    if (t.key == key) return t.value;
  }
  return "<missing>";
}

class KioskHeadless : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    out_ = fs::temp_directory_path() / ("ultrasim-it-" + std::to_string(::getpid()));
    fs::remove_all(out_);
    const std::string command = std::string(ULTRASIM_KIOSK_EXE) + " --headless --case " +
                                ULTRASIM_DEFAULT_CASE + " --out " + out_.string() + " > " +
                                (out_.string() + ".log") + " 2>&1";
    exit_code_ = std::system(command.c_str());
  }
  static void TearDownTestSuite() {
    fs::remove_all(out_);
    fs::remove(out_.string() + ".log");
  }
  static inline fs::path out_;
  static inline int exit_code_ = -1;
};

TEST_F(KioskHeadless, RunsToCompletionAndWritesASaneReport) {
  ASSERT_EQ(exit_code_, 0) << read_text(out_.string() + ".log");
  const std::string json = read_text(out_ / "report.json");
  ASSERT_FALSE(json.empty());
  const double frames = json_number(json, "frames");
  EXPECT_EQ(frames, 571);  // 9.5 s script at one frame per 16,667 µs budget, both ends included
  EXPECT_EQ(json_number(json, "poses_rejected"), 0);
  const double in_contact = json_number(json, "frames_in_contact");
  EXPECT_GT(in_contact, 0.7 * frames);
  EXPECT_LT(in_contact, frames);  // hovering at the start: no contact
  EXPECT_EQ(json_number(json, "diverged_frames"), 0);
  EXPECT_EQ(json_number(json, "method_switches"), 0);
  const double force = json_number(json, "max_contact_force_n");
  EXPECT_GT(force, 0.1);
  EXPECT_LT(force, 100.0);
  const std::size_t frame_time = json.find("\"frame_time\"");
  const double p50 = json_number(json, "p50_us", frame_time);
  const double p99 = json_number(json, "p99_us", frame_time);
  const double max = json_number(json, "max_us", frame_time);
  EXPECT_GT(p50, 0);
  EXPECT_LE(p50, p99);
  EXPECT_LE(p99, max);
  for (const char* name : {"screen-rest.png", "screen-pressed.png", "bscan-rest.png",
                           "bscan-pressed.png", "bscan-lifted.png", "bscan-released.png"}) {
    EXPECT_TRUE(fs::exists(out_ / name)) << name;
  }
}

// The trainee's "save" at the press: the B-scan as a PNG recording the case, the probe's pose
// and the settings.
TEST_F(KioskHeadless, TheSavedImageRecordsCasePoseAndSettings) {
  ASSERT_EQ(exit_code_, 0);
  EXPECT_EQ(json_number(read_text(out_ / "report.json"), "saved_images"), 1);
  const fs::path saved = out_ / "saved-1.png";
  ASSERT_TRUE(fs::exists(saved));
  EXPECT_EQ(read_grey_png(saved).width, 512);
  const auto field = [&saved](const std::string& key) { return png_text_field(saved, key); };
  EXPECT_EQ(field("Case"), "default-upper-arm");
  EXPECT_EQ(field("Method"), "exact");
  EXPECT_EQ(field("Probe position mm"), "-2.000 0.000 8.000");  // the script's 8 mm press
  EXPECT_EQ(field("Depth mm"), "40.000");
  EXPECT_EQ(field("Frozen"), "no");
}

TEST_F(KioskHeadless, ProbeOffTheSkinShowsNoImage) {
  ASSERT_EQ(exit_code_, 0);
  const GreyImage lifted = read_grey_png(out_ / "bscan-lifted.png");
  ASSERT_EQ(lifted.width, 512);
  for (auto p : lifted.pixels) ASSERT_EQ(p, 0) << "an image while the probe is in the air";
  const GreyImage rest = read_grey_png(out_ / "bscan-rest.png");
  int bright = 0;
  for (auto p : rest.pixels) bright += p > 60;
  EXPECT_GT(bright, 0.2 * rest.pixels.size()) << "the resting probe shows tissue";
}

// The script's last phase works the scanner's controls: freeze, press while frozen, then unfreeze
// at 1.5× the depth.
TEST_F(KioskHeadless, FreezeHoldsTheImageAndDepthShowsDeeper) {
  ASSERT_EQ(exit_code_, 0);
  const GreyImage released = read_grey_png(out_ / "bscan-released.png");
  const GreyImage frozen = read_grey_png(out_ / "bscan-frozen.png");
  EXPECT_EQ(frozen.pixels, released.pixels) << "a frozen scanner holds its image while pressed";
  const std::string json = read_text(out_ / "report.json");
  const std::size_t frozen_at = json.find("\"marker\": \"frozen\"");
  ASSERT_NE(frozen_at, std::string::npos);
  EXPECT_GT(json_number(json, "contact_force_n", frozen_at), 1.0) << "the tissue was pressed";

  // 60 mm deep now; the default case's volume ends 45 mm below the skin (probe 0.5 mm in).
  const GreyImage deeper = read_grey_png(out_ / "bscan-deeper.png");
  ASSERT_EQ(deeper.height, 512);
  int tissue_rows = 0, empty_rows = 0;
  for (int y = 0; y < deeper.height; ++y) {
    const double z = (y + 0.5) * 60.0 / deeper.height;
    int lit = 0;
    for (int x = 0; x < deeper.width; ++x) lit += deeper.at(x, y) > 0;
    if (z < 40.0) tissue_rows += lit > deeper.width / 2;
    if (z > 45.5) empty_rows += lit == 0;
  }
  EXPECT_GT(tissue_rows, 0.9 * 40.0 / 60.0 * 512) << "tissue down to 4 cm";
  EXPECT_GT(empty_rows, 0.95 * 14.5 / 60.0 * 512) << "background below the volume";
}

TEST_F(KioskHeadless, VeinCollapsesUnderPressureWhileTheArteryStaysOpen) {
  ASSERT_EQ(exit_code_, 0);
  const GreyImage rest = read_grey_png(out_ / "bscan-rest.png");
  const GreyImage pressed = read_grey_png(out_ / "bscan-pressed.png");
  const GreyImage released = read_grey_png(out_ / "bscan-released.png");
  // Probe centred at x = -2 mm: the vein lies ~6 mm left of the image centre, the artery ~8 mm
  // right; both between 8 and 28 mm deep, above the bone's shadow.
  const double vein_rest = dark_area_mm2(rest, -16, 1, 3, 28);
  const double vein_pressed = dark_area_mm2(pressed, -16, 1, 3, 28);
  const double vein_released = dark_area_mm2(released, -16, 1, 3, 28);
  const double artery_rest = dark_area_mm2(rest, 3, 14, 3, 28);
  const double artery_pressed = dark_area_mm2(pressed, 3, 14, 3, 28);
  RecordProperty("vein_rest_mm2", std::to_string(vein_rest));
  RecordProperty("vein_pressed_mm2", std::to_string(vein_pressed));
  RecordProperty("artery_rest_mm2", std::to_string(artery_rest));
  RecordProperty("artery_pressed_mm2", std::to_string(artery_pressed));
  std::cout << "vein lumen " << vein_rest << " -> " << vein_pressed << " -> " << vein_released
            << " mm2; artery lumen " << artery_rest << " -> " << artery_pressed << " mm2\n";
  EXPECT_GT(vein_rest, 8.0) << "the vein's lumen is visible at rest";
  EXPECT_GT(artery_rest, 15.0) << "the artery's lumen is visible at rest";
  // Measured on the default case with the exact FEM and the transducer face: the vein's dark
  // area falls 12.7 -> 0 mm² at 8 mm (its lumen keeps ~20 % of its labelled area, too thin to
  // show dark: docs/accuracy.md), the artery's 31 -> 30.
  EXPECT_LT(vein_pressed, 0.1 * vein_rest) << "the vein collapses under the probe";
  EXPECT_GT(artery_pressed, 0.9 * artery_rest) << "the artery keeps its lumen";
  EXPECT_GT(vein_released, 0.8 * vein_rest) << "the vein reopens when the pressure is released";
}

// The trainer script: the probe rests over the vessels and the trainee works the controls on
// screen by touch alone (ultrasim-kiosk --script trainer). What the screen then shows is measured.
class KioskTrainer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    out_ = fs::temp_directory_path() / ("ultrasim-trainer-" + std::to_string(::getpid()));
    fs::remove_all(out_);
    const std::string command = std::string(ULTRASIM_KIOSK_EXE) + " --headless --case " +
                                ULTRASIM_DEFAULT_CASE + " --script trainer --out " + out_.string() +
                                " > " + (out_.string() + ".log") + " 2>&1";
    exit_code_ = std::system(command.c_str());
    json_ = read_text(out_ / "report.json");
  }
  static void TearDownTestSuite() {
    fs::remove_all(out_);
    fs::remove(out_.string() + ".log");
  }
  // A number of the snapshot taken at `marker`.
  static double snapshot(const std::string& marker, const std::string& key) {
    const std::size_t at = json_.find("\"marker\": \"" + marker + "\"");
    EXPECT_NE(at, std::string::npos) << marker;
    return at == std::string::npos ? -1.0 : json_number(json_, key, at);
  }
  // The whole snapshot object taken at `marker`.
  static std::string snapshot_text(const std::string& marker) {
    const std::size_t at = json_.find("\"marker\": \"" + marker + "\"");
    if (at == std::string::npos) return {};
    return json_.substr(at, json_.find('}', at) - at);
  }
  static inline fs::path out_;
  static inline int exit_code_ = -1;
  static inline std::string json_;
};

TEST_F(KioskTrainer, EveryScriptedTouchFoundItsControl) {
  ASSERT_EQ(exit_code_, 0) << read_text(out_.string() + ".log");
  EXPECT_EQ(json_number(json_, "taps"), 35);
  EXPECT_EQ(json_number(json_, "taps_missed"), 0) << json_;
  EXPECT_EQ(json_number(json_, "refused_values"), 0);
}

// The compression buttons press the probe 4 × 2 mm: the skin dents by as much, the vein
// collapses and the artery stays open; easing off restores them.
TEST_F(KioskTrainer, CompressionButtonsDentTheSkinAndCollapseTheVein) {
  ASSERT_EQ(exit_code_, 0);
  EXPECT_LT(snapshot("rest", "skin_dent_mm"), 0.05);
  EXPECT_EQ(snapshot("pressed", "compression_mm"), 8.0);
  EXPECT_NEAR(snapshot("pressed", "skin_dent_mm"), 8.0, 0.5);
  EXPECT_EQ(snapshot("released", "compression_mm"), 0.0);
  EXPECT_LT(snapshot("released", "skin_dent_mm"), 0.05);
  const GreyImage rest = read_grey_png(out_ / "bscan-rest.png");
  const GreyImage pressed = read_grey_png(out_ / "bscan-pressed.png");
  const double vein_rest = dark_area_mm2(rest, -16, 1, 3, 28);
  const double vein_pressed = dark_area_mm2(pressed, -16, 1, 3, 28);
  const double artery_rest = dark_area_mm2(rest, 3, 14, 3, 28);
  const double artery_pressed = dark_area_mm2(pressed, 3, 14, 3, 28);
  std::cout << "buttons: vein " << vein_rest << " -> " << vein_pressed << " mm2, artery "
            << artery_rest << " -> " << artery_pressed << " mm2\n";
  EXPECT_GT(vein_rest, 8.0);
  EXPECT_LT(vein_pressed, 0.1 * vein_rest);
  EXPECT_GT(artery_pressed, 0.9 * artery_rest);
}

// Calipers placed by two taps on the B-scan 20 mm apart read 20 mm (a screen pixel is 0.09 mm).
TEST_F(KioskTrainer, CalipersReadTheKnownDistance) {
  ASSERT_EQ(exit_code_, 0);
  EXPECT_EQ(snapshot("pressed", "caliper_mm"), 0.0);
  EXPECT_NEAR(snapshot("measured", "caliper_mm"), 20.0, 0.15);
  EXPECT_NE(snapshot_text("measured").find("\"frozen\": true"), std::string::npos)
      << "measured on the frozen image";
}

TEST_F(KioskTrainer, SaveFreezeGainDepthAndMethodWorkByTouch) {
  ASSERT_EQ(exit_code_, 0);
  const fs::path saved = out_ / "saved-1.png";
  const auto field = [&saved](const std::string& key) { return png_text_field(saved, key); };
  EXPECT_EQ(field("Frozen"), "yes");
  EXPECT_EQ(field("Compression mm"), "8.000");
  EXPECT_EQ(snapshot("released", "gain_db"), 3.0);
  EXPECT_EQ(snapshot("released", "depth_mm"), 50.0);
  EXPECT_EQ(json_number(json_, "method_switches"), 1);
  EXPECT_NE(snapshot_text("orbited").find("\"method\": \"msds-explicit\""), std::string::npos)
      << "picked from the method list";
}

// The settings dialog applies a valid edit (the session restarts with it) and refuses a time
// step stepped below zero with the schema's own words.
TEST_F(KioskTrainer, SettingsAreCheckedByTheConfigSchema) {
  ASSERT_EQ(exit_code_, 0);
  EXPECT_EQ(json_number(json_, "settings_applied"), 1);
  EXPECT_EQ(json_number(json_, "settings_refused"), 1);
  EXPECT_NE(json_.find("msds.time_step_s: out of range: -0.001"), std::string::npos) << json_;
}

// How far (mm, negative = towards the probe) the structures in rows [row0, row1) of `before`
// moved in `after`: the vertical shift with the highest normalised cross-correlation.
double vertical_shift_mm(const GreyImage& before, const GreyImage& after, double depth_mm, int row0,
                         int row1) {
  double best_corr = -2.0;
  int best_shift = 0;
  for (int shift = -120; shift <= 40; ++shift) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    for (int y = row0; y < row1; ++y) {
      const int y2 = y + shift;
      if (y2 < 0 || y2 >= after.height) continue;
      for (int x = 0; x < before.width; ++x) {
        const double a = before.at(x, y), b = after.at(x, y2);
        sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b, n += 1;
      }
    }
    const double cov = sab - sa * sb / n;
    const double corr = cov / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n) + 1e-12);
    if (corr > best_corr) best_corr = corr, best_shift = shift;
  }
  return best_shift * depth_mm / before.height;
}

// The real-data case (PLUS's reconstruction of a spine phantom): pressing moves the deep bony
// echoes towards the probe, as compressed tissue does.
TEST(KioskRealData, PressingLiftsTheSpineEchoesTowardsTheProbe) {
  const fs::path out =
      fs::temp_directory_path() / ("ultrasim-it-plus-" + std::to_string(::getpid()));
  const std::string command = std::string(ULTRASIM_KIOSK_EXE) + " --headless --case " +
                              ULTRASIM_PLUS_CASE + " --out " + out.string() + " > /dev/null 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0);
  const GreyImage rest = read_grey_png(out / "bscan-rest.png");
  const GreyImage pressed = read_grey_png(out / "bscan-pressed.png");
  // The laminae and their shadow, 12–28 mm deep at rest, below the bright near field.
  const double shift_mm = vertical_shift_mm(rest, pressed, 40.0, 150, 350);
  std::cout << "spine echoes moved " << shift_mm << " mm under a 6 mm press\n";
  EXPECT_LT(shift_mm, -1.5) << "compressed tissue brings the deep echoes closer to the probe";
  EXPECT_GT(shift_mm, -6.0) << "but by less than the probe pressed in";
  fs::remove_all(out);
}

// Runs the kiosk with extra arguments and environment; returns its exit status and output.
std::pair<int, std::string> run_kiosk(const std::string& env, const std::string& args) {
  const fs::path log =
      fs::temp_directory_path() / ("ultrasim-it-bad-" + std::to_string(::getpid()));
  const std::string command =
      env + " " + ULTRASIM_KIOSK_EXE + " " + args + " > " + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  std::string output = read_text(log);
  fs::remove(log);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

TEST(KioskBadInput, AMissingCaseGivesOneLineNamingItsFile) {
  const auto [code, output] =
      run_kiosk("", "--headless --case /nonexistent/case --out /tmp/unused");
  EXPECT_EQ(code, 1);
  EXPECT_NE(output.find("/nonexistent/case/case.toml"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists("/tmp/unused/report.json"));
}

TEST(KioskBadInput, NoEglDriverGivesAClearErrorNotACrash) {
  const fs::path out =
      fs::temp_directory_path() / ("ultrasim-it-noegl-" + std::to_string(::getpid()));
  const auto [code, output] = run_kiosk(
      "LIBGL_DRIVERS_PATH=/nonexistent",
      std::string("--headless --case ") + ULTRASIM_DEFAULT_CASE + " --out " + out.string());
  EXPECT_EQ(code, 1);
  EXPECT_NE(output.find("ultrasim-kiosk: eglInitialize failed"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(out / "report.json"));
  fs::remove_all(out);
}

TEST(KioskBadInput, AnUnknownScriptListsTheAvailableOnes) {
  const auto [code, output] = run_kiosk("", std::string("--headless --script zigzag --case ") +
                                                ULTRASIM_DEFAULT_CASE + " --out /tmp/unused");
  EXPECT_EQ(code, 1);
  EXPECT_NE(output.find("sweep-press"), std::string::npos) << output;
}

}  // namespace

namespace {

// [display] backend = "kms" where there is no such device: one line naming it, a failed exit,
// nothing half-written.
TEST(KioskDisplay, AMissingKmsDeviceIsAClearError) {
  const fs::path dir = fs::temp_directory_path() / ("ultrasim-kms-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "app.toml")
      << "[display]\nbackend = \"kms\"\nkms_device = \"/dev/dri/ultrasim-none\"\n";
  const std::string command = std::string(ULTRASIM_KIOSK_EXE) + " --headless --case " +
                              ULTRASIM_DEFAULT_CASE + " --config " + (dir / "app.toml").string() +
                              " --out " + (dir / "out").string() + " > " + (dir / "log").string() +
                              " 2>&1";
  const int status = std::system(command.c_str());
  const std::string log = read_text(dir / "log");
  EXPECT_NE(status, 0);
  EXPECT_NE(log.find("KMS display: cannot open /dev/dri/ultrasim-none"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir / "out" / "report.json"));
  fs::remove_all(dir);
}

}  // namespace

namespace {

// The kiosk itself (no --headless): the configured display and probe in real time, frames paced
// to their budget, until a signal; it then finishes the frame, restores the display and writes
// its report. (How many frames fit in a wall-clock time depends on the machine's load: the
// counts below are the kiosk's own, not a stopwatch's.)
TEST(KioskMode, RunsInRealTimeUntilASignal) {
  const fs::path dir = fs::temp_directory_path() / ("ultrasim-kiosk-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string kiosk = std::string(ULTRASIM_KIOSK_EXE) + " --case " + ULTRASIM_DEFAULT_CASE;
  // One second of frames, one per 16.7 ms budget, never faster than real time.
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(std::system((kiosk + " --kiosk-seconds 1 --out " + (dir / "timed").string() + " > " +
                         dir.string() + ".log 2>&1")
                            .c_str()),
            0)
      << read_text(dir.string() + ".log");
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  const std::string timed = read_text(dir / "timed" / "report.json");
  EXPECT_EQ(json_number(timed, "frames"), 61);  // 1 s / 16,667 µs = 59, plus both ends
  EXPECT_FALSE(fs::exists(dir / "timed" / "screen-rest.png"));  // no screenshots
  // Stopped by SIGINT long before its hour is up: the report is still written.
  std::system(("timeout -s INT 3 " + kiosk + " --kiosk-seconds 3600 --out " +
               (dir / "stopped").string() + " > " + dir.string() + ".log 2>&1")
                  .c_str());  // timeout's status says it sent the signal (124)
  const std::string stopped = read_text(dir / "stopped" / "report.json");
  ASSERT_FALSE(stopped.empty()) << read_text(dir.string() + ".log");
  EXPECT_LT(json_number(stopped, "frames"), 3600 * 60);
  fs::remove_all(dir);
  fs::remove(dir.string() + ".log");
}

}  // namespace
