// The run report's recovery log: runs of frames with one recovery on one case and method become
// one event; anything else starts a new one; past the cap events are only counted.

#include "ultrasim/kiosk/recovery_events.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "ultrasim/kiosk/run_report.hpp"

namespace ultrasim::kiosk {
namespace {

using sim::Recovery;

TEST(RecoveryEvents, ARunOfFramesWithOneRecoveryIsOneEventWithItsStrongestPress) {
  RecoveryEvents log;
  log.record(10, 0.1, "arm", "pcg", Recovery::kNone, 5.0);
  log.record(11, 0.2, "arm", "pcg", Recovery::kKeptLastGood, 40.0);
  log.record(12, 0.3, "arm", "pcg", Recovery::kKeptLastGood, 90.0);
  log.record(13, 0.4, "arm", "pcg", Recovery::kKeptLastGood, 60.0);
  log.record(14, 0.5, "arm", "pcg", Recovery::kNone, 5.0);
  ASSERT_EQ(log.events().size(), 1u);
  const RecoveryEvent& e = log.events()[0];
  EXPECT_EQ(e.kind, Recovery::kKeptLastGood);
  EXPECT_EQ(e.first_frame, 11);
  EXPECT_EQ(e.frames, 3);
  EXPECT_DOUBLE_EQ(e.time_s, 0.2);
  EXPECT_EQ(e.case_name, "arm");
  EXPECT_EQ(e.method, "pcg");
  EXPECT_DOUBLE_EQ(e.max_contact_force_n, 90.0);
  EXPECT_EQ(log.dropped(), 0);
}

TEST(RecoveryEvents, AnotherKindCaseOrMethodOrAGapStartsANewEvent) {
  RecoveryEvents log;
  log.record(1, 0.0, "arm", "pcg", Recovery::kKeptLastGood, 1.0);
  log.record(2, 0.0, "arm", "pcg", Recovery::kSubstepped, 1.0);              // another kind
  log.record(3, 0.0, "arm", "msds-implicit", Recovery::kSubstepped, 1.0);    // another method
  log.record(4, 0.0, "spine", "msds-implicit", Recovery::kSubstepped, 1.0);  // another case
  log.record(6, 0.0, "spine", "msds-implicit", Recovery::kSubstepped, 1.0);  // frame 5 was fine
  log.record(7, 0.0, "spine", "msds-implicit", Recovery::kReset, std::nan(""));
  ASSERT_EQ(log.events().size(), 6u);
  for (const RecoveryEvent& e : log.events()) EXPECT_EQ(e.frames, 1);
  EXPECT_EQ(log.events()[5].kind, Recovery::kReset);
  EXPECT_EQ(log.events()[5].max_contact_force_n, 0.0) << "no NaN in the report's JSON";
  EXPECT_EQ(sim::recovery_key(Recovery::kKeptLastGood), "kept-last-good");
  EXPECT_EQ(sim::recovery_key(Recovery::kSubstepped), "substepped");
  EXPECT_EQ(sim::recovery_key(Recovery::kReset), "reset");
}

TEST(RecoveryEvents, AnotherCauseStartsANewEventAndEachKeepsItsCause) {
  RecoveryEvents log;
  using sim::DivergenceCause;
  log.record(1, 0.0, "arm", "msds-explicit", Recovery::kKeptLastGood, 1.0,
             DivergenceCause::kRunaway);
  log.record(2, 0.0, "arm", "msds-explicit", Recovery::kKeptLastGood, 1.0,
             DivergenceCause::kInverted);
  log.record(3, 0.0, "arm", "msds-explicit", Recovery::kKeptLastGood, 1.0,
             DivergenceCause::kInverted);
  ASSERT_EQ(log.events().size(), 2u);
  EXPECT_EQ(log.events()[0].cause, DivergenceCause::kRunaway);
  EXPECT_EQ(log.events()[0].frames, 1);
  EXPECT_EQ(log.events()[1].cause, DivergenceCause::kInverted);
  EXPECT_EQ(log.events()[1].frames, 2);
}

// report.json: each event with its cause, and the diverged frames counted by cause.
TEST(RecoveryEvents, TheReportWritesEachEventsCauseAndTheDivergedFramesByCause) {
  RunReport report;
  report.causes[static_cast<std::size_t>(sim::DivergenceCause::kRunaway)] = 3;
  report.causes[static_cast<std::size_t>(sim::DivergenceCause::kInverted)] = 2;
  report.recovery_events.record(7, 0.1, "arm", "msds-explicit", Recovery::kKeptLastGood, 9.0,
                                sim::DivergenceCause::kRunaway);
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / "recovery_events_test_report.json";
  write_report_json(path, report);
  std::stringstream json;
  json << std::ifstream(path).rdbuf();
  std::filesystem::remove(path);
  EXPECT_NE(json.str().find("\"diverged_by_cause\": {\"non-finite\": 0, \"energy\": 0, "
                            "\"runaway\": 3, \"inverted\": 2, \"seam-torn\": 0}"),
            std::string::npos)
      << json.str();
  EXPECT_NE(json.str().find("{\"kind\": \"kept-last-good\", \"cause\": \"runaway\", "
                            "\"first_frame\": 7, \"length_frames\": 1"),
            std::string::npos)
      << json.str();
}

TEST(RecoveryEvents, PastTheCapEventsAreCountedNotKept) {
  RecoveryEvents log;
  const auto n = static_cast<std::int64_t>(RecoveryEvents::kMaxEvents);
  for (std::int64_t i = 0; i < n + 10; ++i) {
    // Two-frame events, a fine frame between them.
    log.record(3 * i, 0.0, "arm", "pcg", Recovery::kKeptLastGood, static_cast<double>(i));
    log.record(3 * i + 1, 0.0, "arm", "pcg", Recovery::kKeptLastGood, static_cast<double>(i));
  }
  ASSERT_EQ(log.events().size(), RecoveryEvents::kMaxEvents);
  EXPECT_EQ(log.dropped(), 10);
  EXPECT_EQ(log.events().back().frames, 2) << "the last kept event still grows";
  EXPECT_EQ(log.events().back().first_frame, 3 * (n - 1));
}

}  // namespace
}  // namespace ultrasim::kiosk
