#include "ultrasim/config/app_settings.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "config_test_support.hpp"
#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config {
namespace {

using testing::error_of;
using ::testing::HasSubstr;
using ::testing::Not;
using testing::ScratchDir;

void expect_same(const AppSettings& a, const AppSettings& b) {
  EXPECT_EQ(a.display.backend, b.display.backend);
  EXPECT_EQ(a.display.width_px, b.display.width_px);
  EXPECT_EQ(a.display.height_px, b.display.height_px);
  EXPECT_EQ(a.display.kms_device, b.display.kms_device);
  EXPECT_EQ(a.display.kms_connector, b.display.kms_connector);
  EXPECT_EQ(a.display.kms_mode_width_px, b.display.kms_mode_width_px);
  EXPECT_EQ(a.display.kms_mode_height_px, b.display.kms_mode_height_px);
  EXPECT_EQ(a.display.kms_refresh_hz, b.display.kms_refresh_hz);
  EXPECT_EQ(a.display.kms_legacy, b.display.kms_legacy);
  EXPECT_EQ(a.bscan.slicer, b.bscan.slicer);
  EXPECT_EQ(a.bscan.width_px, b.bscan.width_px);
  EXPECT_EQ(a.bscan.height_px, b.bscan.height_px);
  EXPECT_EQ(a.bscan.gain_db, b.bscan.gain_db);
  EXPECT_EQ(a.bscan.tgc_db, b.bscan.tgc_db);
  EXPECT_EQ(a.bscan.dynamic_range_db, b.bscan.dynamic_range_db);
  EXPECT_EQ(a.bscan.scan_lines, b.bscan.scan_lines);
  EXPECT_EQ(a.bscan.samples_per_line, b.bscan.samples_per_line);
  EXPECT_EQ(a.bscan.background_grey, b.bscan.background_grey);
  EXPECT_EQ(a.fem.pcg_iterations_per_frame, b.fem.pcg_iterations_per_frame);
  EXPECT_EQ(a.fem.relative_tolerance, b.fem.relative_tolerance);
  EXPECT_EQ(a.fem.contact.model, b.fem.contact.model);
  EXPECT_EQ(a.fem.contact.friction_coefficient, b.fem.contact.friction_coefficient);
  EXPECT_EQ(a.msds.contact.model, b.msds.contact.model);
  EXPECT_EQ(a.msds.contact.friction_coefficient, b.msds.contact.friction_coefficient);
  EXPECT_EQ(a.corotational.pcg_iterations_per_frame, b.corotational.pcg_iterations_per_frame);
  EXPECT_EQ(a.corotational.relative_tolerance, b.corotational.relative_tolerance);
  EXPECT_EQ(a.corotational.max_inverted_fraction, b.corotational.max_inverted_fraction);
  EXPECT_EQ(a.corotational.contact.model, b.corotational.contact.model);
  EXPECT_EQ(a.corotational.contact.friction_coefficient,
            b.corotational.contact.friction_coefficient);
  EXPECT_EQ(a.collider.radius_mm, b.collider.radius_mm);
  EXPECT_EQ(a.stitching.spring_stiffness_per_modulus_mm,
            b.stitching.spring_stiffness_per_modulus_mm);
  EXPECT_EQ(a.stitching.split_overlap_stiffness, b.stitching.split_overlap_stiffness);
  EXPECT_EQ(a.stitching.selective, b.stitching.selective);
  EXPECT_EQ(a.stitching.extra_sub_volumes_per_frame, b.stitching.extra_sub_volumes_per_frame);
  EXPECT_EQ(a.stitching.exchanges_per_frame, b.stitching.exchanges_per_frame);
  EXPECT_EQ(a.stitching.explicit_msds_exchanges_per_frame,
            b.stitching.explicit_msds_exchanges_per_frame);
  EXPECT_EQ(a.stitching.implicit_msds_exchanges_per_frame,
            b.stitching.implicit_msds_exchanges_per_frame);
  EXPECT_EQ(a.stitching.corotational_exchanges_per_frame,
            b.stitching.corotational_exchanges_per_frame);
  EXPECT_EQ(a.corotational.rotation_update_tolerance, b.corotational.rotation_update_tolerance);
  EXPECT_EQ(a.corotational.max_rotation_updates_fraction,
            b.corotational.max_rotation_updates_fraction);
  EXPECT_EQ(a.stitching.corotational_turn_check_interval_frames,
            b.stitching.corotational_turn_check_interval_frames);
  EXPECT_EQ(a.stitching.corotational_rotation_update_interval_frames,
            b.stitching.corotational_rotation_update_interval_frames);
  EXPECT_EQ(a.stitching.corotational_update_turns_held, b.stitching.corotational_update_turns_held);
  EXPECT_EQ(a.stitching.coarse_correction, b.stitching.coarse_correction);
  EXPECT_EQ(a.stitching.seam_load_rate, b.stitching.seam_load_rate);
  EXPECT_EQ(a.stitching.sleep_force_mn, b.stitching.sleep_force_mn);
  EXPECT_EQ(a.stitching.sleep_motion_mm, b.stitching.sleep_motion_mm);
  EXPECT_EQ(a.frame.budget_us, b.frame.budget_us);
  EXPECT_EQ(a.frame.simulation_budget_us, b.frame.simulation_budget_us);
  EXPECT_EQ(a.frame.bscan_budget_us, b.frame.bscan_budget_us);
  EXPECT_EQ(a.frame.view_budget_us, b.frame.view_budget_us);
  EXPECT_EQ(a.frame.render_budget_us, b.frame.render_budget_us);
  const auto& p = a.probe;
  const auto& q = b.probe;
  EXPECT_EQ(p.source, q.source);
  EXPECT_EQ(p.motion_file, q.motion_file);
  EXPECT_EQ(p.can_interface, q.can_interface);
  EXPECT_EQ(p.can_log, q.can_log);
  EXPECT_EQ(p.replay_speed, q.replay_speed);
  EXPECT_EQ(p.replay_loop, q.replay_loop);
  EXPECT_EQ(p.imu_rate_hz, q.imu_rate_hz);
  EXPECT_EQ(p.pivot_mm, q.pivot_mm);
  EXPECT_EQ(p.compression_mm_per_n, q.compression_mm_per_n);
  EXPECT_EQ(p.max_compression_mm, q.max_compression_mm);
  EXPECT_EQ(p.camera_device, q.camera_device);
  EXPECT_EQ(p.camera_images, q.camera_images);
  EXPECT_EQ(p.camera_fps, q.camera_fps);
  EXPECT_EQ(p.camera_width_px, q.camera_width_px);
  EXPECT_EQ(p.camera_height_px, q.camera_height_px);
  EXPECT_EQ(p.camera_intrinsics, q.camera_intrinsics);
  EXPECT_EQ(p.camera_distortion, q.camera_distortion);
  EXPECT_EQ(p.camera_pose, q.camera_pose);
  EXPECT_EQ(p.probe_in_body, q.probe_in_body);
  EXPECT_EQ(p.dodecahedron_edge_mm, q.dodecahedron_edge_mm);
  EXPECT_EQ(p.keyboard_start_mm, q.keyboard_start_mm);
  EXPECT_EQ(p.keyboard_speed_mm_per_s, q.keyboard_speed_mm_per_s);
  EXPECT_EQ(p.keyboard_device, q.keyboard_device);
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream stream(path, std::ios::binary);
  std::ostringstream text;
  text << stream.rdbuf();
  return text.str();
}

const std::filesystem::path kDefaultFile =
    std::filesystem::path(ULTRASIM_CONFIG_DEFAULT_DIR) / "app.toml";

TEST(AppSettings, EmptyTextGivesStructDefaults) {
  expect_same(parse_app_settings("", "empty.toml"), AppSettings{});
}

TEST(AppSettings, EmptyFileGivesStructDefaults) {
  const ScratchDir dir;
  expect_same(load_app_settings(dir.write("app.toml", "")), AppSettings{});
}

TEST(AppSettings, CheckedInDefaultFileMatchesGenerator) {
  const std::string expected = default_app_toml();
  if (read_file(kDefaultFile) != expected) {
    // Leave the generated text beside the build so that updating the file is one copy.
    const auto generated = std::filesystem::path(ULTRASIM_BINARY_DIR) / "generated_app.toml";
    std::ofstream(generated, std::ios::binary) << expected;
    FAIL() << kDefaultFile << " is out of date with config::default_app_toml(); the generated "
           << "text is in " << generated << ": copy it over.";
  }
}

TEST(AppSettings, CheckedInDefaultFileLoadsToStructDefaults) {
  expect_same(load_app_settings(kDefaultFile), AppSettings{});
}

TEST(AppSettings, EveryFieldRoundTripsThroughFormat) {
  AppSettings changed;
  changed.display.width_px = 1920;
  changed.display.height_px = 1080;
  changed.display.backend = render::DisplayBackend::kKms;
  changed.display.kms_device = "/dev/dri/card1";
  changed.display.kms_connector = "HDMI-A-1";
  changed.display.kms_mode_width_px = 1920;
  changed.display.kms_mode_height_px = 1080;
  changed.display.kms_refresh_hz = 60;
  changed.display.kms_legacy = true;
  changed.bscan.slicer = imaging::SlicerMethod::kPublished;
  changed.bscan.width_px = 300;
  changed.bscan.height_px = 200;
  changed.bscan.gain_db = -12.25;
  changed.bscan.tgc_db = {0.0, 1.5, 3.0, 4.5, 6.0, 7.5, 9.0, 10.5};
  changed.bscan.dynamic_range_db = 45.0;
  changed.bscan.scan_lines = 128;
  changed.bscan.samples_per_line = 300;
  changed.bscan.background_grey = 17;
  changed.fem.pcg_iterations_per_frame = 77;
  changed.fem.relative_tolerance = 0.1 + 0.2;  // not exactly representable in short decimal
  changed.corotational.pcg_iterations_per_frame = 33;
  changed.corotational.max_inverted_fraction = 0.0125;
  changed.corotational.contact = {sim::HeldContactModel::kStick, 0.3};
  changed.collider.radius_mm = 12.5;
  changed.stitching.spring_stiffness_per_modulus_mm = 7.5;
  changed.stitching.split_overlap_stiffness = false;
  changed.stitching.selective = false;
  changed.stitching.extra_sub_volumes_per_frame = 3;
  changed.stitching.exchanges_per_frame = 4;
  changed.stitching.explicit_msds_exchanges_per_frame = 3;
  changed.stitching.implicit_msds_exchanges_per_frame = 5;
  changed.stitching.corotational_exchanges_per_frame = 2;
  changed.corotational.rotation_update_tolerance = 0.0025;
  changed.corotational.max_rotation_updates_fraction = 0.125;
  changed.stitching.corotational_turn_check_interval_frames = 3;
  changed.stitching.corotational_rotation_update_interval_frames = 3;
  changed.stitching.corotational_update_turns_held = 0;
  changed.stitching.coarse_correction = false;
  changed.stitching.seam_load_rate = 0.5;
  changed.stitching.sleep_force_mn = 0.25;
  changed.stitching.sleep_motion_mm = 2e-3;
  changed.fem.contact.model = sim::HeldContactModel::kStick;
  changed.fem.contact.friction_coefficient = 0.3;
  changed.msds.contact.friction_coefficient = 0.15;
  changed.frame.budget_us = 33'333;
  changed.frame.simulation_budget_us = 7'000;
  changed.frame.bscan_budget_us = 2'500;
  changed.frame.view_budget_us = 300;
  changed.frame.render_budget_us = 20'000;
  changed.probe.source = hal::ProbeSourceKind::kCameraImages;
  changed.probe.motion_file = "sweep.motion";
  changed.probe.can_interface = "vcan0";
  changed.probe.can_log = "probe.log";
  changed.probe.replay_speed = 2.5;
  changed.probe.replay_loop = false;
  changed.probe.imu_rate_hz = 400.0;
  changed.probe.pivot_mm = {1.0, -2.5, 3.0};
  changed.probe.compression_mm_per_n = 0.5;
  changed.probe.max_compression_mm = 12.0;
  changed.probe.camera_device = "/dev/video2";
  changed.probe.camera_images = "frames";
  changed.probe.camera_fps = 120.0;
  changed.probe.camera_width_px = 1280;
  changed.probe.camera_height_px = 720;
  changed.probe.camera_intrinsics = {900.0, 905.0, 640.5, 360.25};
  changed.probe.camera_distortion = {0.1, -0.2, 0.001, 0.002, 0.05};
  changed.probe.camera_pose = {10.0, 20.0, -350.0, 180.0, 0.0, 0.0};
  changed.probe.probe_in_body = {0.0, 5.0, 70.0, 0.0, 90.0, 0.0};
  changed.probe.dodecahedron_edge_mm = 30.0;
  changed.probe.keyboard_start_mm = {5.0, 6.0, -7.0};
  changed.probe.keyboard_speed_mm_per_s = 80.0;
  changed.probe.keyboard_device = "/dev/input/event3";
  expect_same(parse_app_settings(format_app_toml(changed), "formatted.toml"), changed);
}

TEST(AppSettings, EveryKeyIsReadFromItsTable) {
  const AppSettings s = parse_app_settings(R"(
[display]
backend = "offscreen"
width_px = 800
height_px = 600
[bscan]
width_px = 256
height_px = 128
gain_db = 6
background_grey = 5
[fem]
pcg_iterations_per_frame = 40
relative_tolerance = 1e-6
[msds]
contact = "stick"
friction_coefficient = 0.2
[corotational]
max_inverted_fraction = 0.02
[collider]
radius_mm = 500
[frame]
budget_us = 8333
)",
                                           "all.toml");
  EXPECT_EQ(s.display.backend, render::DisplayBackend::kOffscreen);
  EXPECT_EQ(s.display.width_px, 800);
  EXPECT_EQ(s.display.height_px, 600);
  EXPECT_EQ(s.bscan.width_px, 256);
  EXPECT_EQ(s.bscan.height_px, 128);
  EXPECT_EQ(s.bscan.gain_db, 6.0);  // a TOML integer is accepted where a number is expected
  EXPECT_EQ(s.bscan.background_grey, 5);
  EXPECT_EQ(s.fem.pcg_iterations_per_frame, 40);
  EXPECT_EQ(s.fem.relative_tolerance, 1e-6);
  EXPECT_EQ(s.msds.contact.model, sim::HeldContactModel::kStick);
  EXPECT_EQ(s.msds.contact.friction_coefficient, 0.2);
  EXPECT_EQ(s.corotational.max_inverted_fraction, 0.02);
  EXPECT_EQ(s.collider.radius_mm, 500.0);  // closed upper bound
  EXPECT_EQ(s.frame.budget_us, 8333);
}

TEST(AppSettings, MissingKeysKeepDefaults) {
  const AppSettings s = parse_app_settings("[bscan]\ngain_db = 3.5\n", "partial.toml");
  AppSettings expected;
  expected.bscan.gain_db = 3.5;
  expect_same(s, expected);
}

TEST(AppSettings, UnknownKeyNamesFileLineKeyAndSuggestion) {
  const auto caught = error_of(
      [] { (void)parse_app_settings("[bscan]\nwidth_px = 64\n\nwidht_px = 32\n", "app.toml"); });
  EXPECT_EQ(caught.message,
            "app.toml:4:1: bscan.widht_px: unknown key (did you mean \"width_px\"?); allowed: "
            "slicer, width_px, height_px, gain_db, tgc_db, dynamic_range_db, background_grey, "
            "scan_lines, samples_per_line");
}

TEST(AppSettings, UnknownTableIsAnError) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[fem]\n[colider]\nradius_mm = 3\n", "app.toml"); });
  EXPECT_EQ(caught.details.line, 2);
  EXPECT_EQ(caught.details.key, "colider");
  EXPECT_THAT(caught.message, HasSubstr("did you mean \"collider\"?"));
  EXPECT_THAT(
      caught.message,
      HasSubstr(
          "allowed: display, bscan, sim, fem, exact, corotational, hyperelastic, msds, stitching, "
          "collider, frame"));
}

TEST(AppSettings, FarOffUnknownKeyGetsNoSuggestion) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[frame]\nvsync = true\n", "app.toml"); });
  EXPECT_EQ(caught.details.key, "frame.vsync");
  EXPECT_THAT(caught.message, Not(HasSubstr("did you mean")));
}

TEST(AppSettings, WrongTypeSaysExpectedAndGot) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[display]\nwidth_px = \"wide\"\n", "app.toml"); });
  EXPECT_EQ(caught.message,
            "app.toml:2:12: display.width_px: wrong type: expected integer, got string; allowed: "
            "integer in [64, 7680]");
}

TEST(AppSettings, FloatForIntegerIsWrongType) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[frame]\nbudget_us = 16667.0\n", "app.toml"); });
  EXPECT_THAT(caught.message, HasSubstr("expected integer, got float"));
}

TEST(AppSettings, TableOfWrongTypeIsAnError) {
  const auto caught = error_of([] { (void)parse_app_settings("fem = 3\n", "app.toml"); });
  EXPECT_THAT(caught.message, HasSubstr("app.toml:1:7: fem: wrong type: expected table, got "
                                        "integer; allowed: a table of: pcg_iterations_per_frame"));
}

TEST(AppSettings, OutOfRangeShowsAllowedRange) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[bscan]\ngain_db = 90\n", "app.toml"); });
  EXPECT_EQ(caught.message,
            "app.toml:2:11: bscan.gain_db: out of range: 90.0; allowed: number in [-40, 40]");
  EXPECT_EQ(caught.details.allowed, "number in [-40, 40]");
}

TEST(AppSettings, OpenBoundsAreExcluded) {
  EXPECT_THAT(error_of([] {
                (void)parse_app_settings("[fem]\nrelative_tolerance = 0.0\n", "a.toml");
              }).message,
              HasSubstr("allowed: number in (0, 1)"));
  EXPECT_THAT(
      error_of([] { (void)parse_app_settings("[collider]\nradius_mm = 0.5\n", "a.toml"); }).message,
      HasSubstr("allowed: number in (0.5, 500]"));
  EXPECT_THAT(
      error_of([] { (void)parse_app_settings("[collider]\nradius_mm = nan\n", "a.toml"); }).message,
      HasSubstr("out of range: nan"));
}

TEST(AppSettings, IntegerRangesAreInclusive) {
  const AppSettings s = parse_app_settings(
      "[frame]\nbudget_us = 1000\n[display]\nwidth_px = 7680\nheight_px = 64\n", "a.toml");
  EXPECT_EQ(s.frame.budget_us, 1000);
  EXPECT_EQ(s.display.width_px, 7680);
  EXPECT_EQ(s.display.height_px, 64);
  EXPECT_THAT(
      error_of([] { (void)parse_app_settings("[frame]\nbudget_us = 999\n", "a.toml"); }).message,
      HasSubstr("frame.budget_us: out of range: 999; allowed: integer in [1000, 1000000]"));
}

TEST(AppSettings, BadEnumStringListsAllowedValues) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[display]\nbackend = \"vulkan\"\n", "app.toml"); });
  EXPECT_EQ(caught.message,
            "app.toml:2:11: display.backend: unknown value \"vulkan\"; allowed: one of "
            "\"offscreen\", \"kms\"");
}

TEST(AppSettings, SyntaxErrorHasLineAndColumn) {
  const auto caught =
      error_of([] { (void)parse_app_settings("[bscan]\ngain_db = = 3\n", "app.toml"); });
  EXPECT_EQ(caught.details.line, 2);
  EXPECT_GT(caught.details.column, 0);
  EXPECT_THAT(caught.message, HasSubstr("app.toml:2:"));
  EXPECT_THAT(caught.message, HasSubstr("TOML syntax error"));
}

TEST(AppSettings, DuplicateKeyIsASyntaxError) {
  const auto caught = error_of([] {
    (void)parse_app_settings("[fem]\nrelative_tolerance = 0.1\nrelative_tolerance = 0.2\n",
                             "app.toml");
  });
  EXPECT_EQ(caught.details.line, 3);
}

TEST(AppSettings, MissingFileIsAnError) {
  const ScratchDir dir;
  const auto missing = dir.path() / "nope.toml";
  const auto caught = error_of([&] { (void)load_app_settings(missing); });
  EXPECT_THAT(caught.message, HasSubstr(missing.string()));
  EXPECT_THAT(caught.message, HasSubstr("file not found"));
}

TEST(AppSettings, FileErrorsNameThePath) {
  const ScratchDir dir;
  const auto file = dir.write("app.toml", "[bscan]\nbackground_grey = 256\n");
  const auto caught = error_of([&] { (void)load_app_settings(file); });
  EXPECT_EQ(caught.details.file, file.string());
  EXPECT_EQ(caught.message.rfind(file.string() + ":2:19: bscan.background_grey: ", 0), 0u)
      << caught.message;
}

TEST(AppSettings, MessagesAreOneLine) {
  const auto caught = error_of(
      [] { (void)parse_app_settings("[bscan]\ngain_db = \"\"\"\nloud\"\"\"\n", "app.toml"); });
  EXPECT_EQ(caught.message.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace ultrasim::config
