// candump -l logs: lines as can-utils writes them, bad lines named by line and field, and the
// replay bus's timing on a manual clock.

#include <gtest/gtest.h>

#include <string>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/can_replay/replay_bus.hpp"

namespace ultrasim::drivers::can_replay {
namespace {

std::string error_of(const std::string& line) {
  try {
    parse_candump_line(line, "probe.log", 7);
  } catch (const CandumpError& e) {
    return e.what();
  }
  return "(parsed)";
}

TEST(CandumpLog, ReadsAndWritesTheLinesCandumpWrites) {
  // As `candump -l can0` and python-can's CanutilsLogWriter write them.
  const std::string standard = "(1700000000.012345) can0 101#000000C0DB0507D8";
  const CandumpRecord r = parse_candump_line(standard, "probe.log", 1);
  EXPECT_EQ(r.timestamp_us, 1'700'000'000'012'345);
  EXPECT_EQ(r.interface, "can0");
  EXPECT_EQ(r.frame.id, 0x101u);
  EXPECT_FALSE(r.frame.extended);
  EXPECT_EQ(r.frame.length, 8);
  EXPECT_EQ(r.frame.data[3], 0xC0);
  EXPECT_EQ(r.frame.data[7], 0xD8);
  EXPECT_EQ(format_candump_line(r), standard);

  const std::string extended = "(0.000001) vcan0 18FF0102#01";
  const CandumpRecord e = parse_candump_line(extended, "probe.log", 2);
  EXPECT_TRUE(e.frame.extended);
  EXPECT_EQ(e.frame.id, 0x18FF0102u);
  EXPECT_EQ(e.frame.length, 1);
  EXPECT_EQ(format_candump_line(e), extended);

  const std::string remote = "(12.500000) can0 100#R";
  const CandumpRecord rtr = parse_candump_line(remote, "probe.log", 3);
  EXPECT_TRUE(rtr.frame.remote);
  EXPECT_EQ(rtr.frame.length, 0);
  EXPECT_EQ(format_candump_line(rtr), remote);
  // python-can and can-utils' newer candump add the direction: R received, T transmitted.
  const std::string sent = "(1.600000) can0 101#0102 T";
  const CandumpRecord tx = parse_candump_line(sent, "probe.log", 5);
  EXPECT_EQ(tx.direction, 'T');
  EXPECT_EQ(tx.frame.length, 2);
  EXPECT_EQ(format_candump_line(tx), sent);
  EXPECT_EQ(error_of("(1.000000) can0 101#0102 X"),
            "probe.log:7: direction: expected R or T after the frame, got 'X'");
  const std::string empty = "(12.500000) can0 7FF#";
  EXPECT_EQ(parse_candump_line(empty, "probe.log", 4).frame.length, 0);
  EXPECT_EQ(format_candump_line(parse_candump_line(empty, "probe.log", 4)), empty);
}

TEST(CandumpLog, BadLinesNameTheLineAndTheField) {
  EXPECT_EQ(error_of("1700000000.012345 can0 101#00"),
            "probe.log:7: expected '(' before the timestamp");
  EXPECT_EQ(error_of("(1700000000.0123) can0 101#00"),
            "probe.log:7: timestamp: expected (seconds.microseconds) with 6 digits of "
            "microseconds, got '(1700000000.0123)'");
  EXPECT_EQ(error_of("(1.000000) can0 1011#00"),
            "probe.log:7: identifier: expected 3 hex digits (standard) or 8 (extended), got "
            "'1011'");
  EXPECT_EQ(error_of("(1.000000) can0 10G#00"),
            "probe.log:7: identifier: '10G' is not hexadecimal");
  EXPECT_EQ(error_of("(1.000000) can0 101#001"),
            "probe.log:7: data: expected 0 to 8 bytes as pairs of hex digits, got '001'");
  EXPECT_EQ(error_of("(1.000000) can0 101##10011"),
            "probe.log:7: frame: CAN FD (##) is not supported");
  EXPECT_EQ(error_of("(1.000000) can0 20000080#0000000000000000"),
            "probe.log:7: identifier: error frames are not supported");
  EXPECT_EQ(error_of("(1.000000) can0"),
            "probe.log:7: interface: expected a name after the timestamp");
  try {
    parse_candump_log("(1.000000) can0 101#00\n\n(2.000000) can0 101#0\n", "probe.log");
    FAIL() << "a bad third line was read";
  } catch (const CandumpError& e) {
    EXPECT_EQ(e.line(), 3);
  }
  EXPECT_EQ(error_of("(-5.000000) can0 101#00"),
            "probe.log:7: timestamp: '(-5.000000)' is out of range");
  EXPECT_EQ(error_of("(1.-00001) can0 101#00"),
            "probe.log:7: timestamp: '(1.-00001)' is out of range");
  EXPECT_EQ(error_of("(99999999999999.000000) can0 101#00"),
            "probe.log:7: timestamp: '(99999999999999.000000)' is out of range");
  EXPECT_THROW(read_candump_log("/nonexistent/probe.log"), CandumpError);
}

TEST(ReplayBus, PlaysTheLogBackAtItsOwnPaceOnTheClock) {
  const auto records = parse_candump_log(
      "(100.000000) can0 101#01\n(100.005000) can0 101#02\n(100.010000) can0 100#03\n",
      "probe.log");
  hal::ManualClock clock(1'000'000);
  ReplayBus bus(records, clock);
  hal::ReceivedCanFrame got;
  ASSERT_TRUE(bus.receive(got));  // the first frame is due at once
  EXPECT_EQ(got.frame.data[0], 1);
  EXPECT_EQ(got.timestamp_us, 1'000'000);
  EXPECT_FALSE(bus.receive(got)) << "the second is 5 ms later";
  clock.advance_us(4'999);
  EXPECT_FALSE(bus.receive(got));
  clock.advance_us(1);
  ASSERT_TRUE(bus.receive(got));
  EXPECT_EQ(got.frame.data[0], 2);
  EXPECT_EQ(got.timestamp_us, 1'005'000);
  clock.advance_us(100'000);  // late: the third is still stamped when it was due
  ASSERT_TRUE(bus.receive(got));
  EXPECT_EQ(got.frame.id, 0x100u);
  EXPECT_EQ(got.timestamp_us, 1'010'000);
  EXPECT_FALSE(bus.receive(got));
  EXPECT_TRUE(bus.finished());
  EXPECT_EQ(bus.stats().rx_frames, 3u);

  hal::CanFrame command;
  command.id = 0x200;
  command.length = 1;
  EXPECT_TRUE(bus.send(command, clock.now_us() + 1000));
  EXPECT_FALSE(bus.send(command, clock.now_us() - 1)) << "past its deadline";
  ASSERT_EQ(bus.sent_frames().size(), 1u);
  EXPECT_EQ(bus.stats().tx_failures, 1u);
}

TEST(ReplayBus, LoopsAndSpeedsUpAndRefusesLogsItCannotPlay) {
  const auto records =
      parse_candump_log("(0.000000) can0 101#01\n(0.010000) can0 101#02\n", "probe.log");
  hal::ManualClock clock;
  ReplayBus bus(records, clock, {.speed = 2.0, .loop = true});
  hal::ReceivedCanFrame got;
  ASSERT_TRUE(bus.receive(got));
  clock.advance_us(5'000);  // 10 ms of log at twice the speed
  ASSERT_TRUE(bus.receive(got));
  EXPECT_EQ(got.frame.data[0], 2);
  EXPECT_FALSE(bus.receive(got));
  // The next pass starts one mean interval (10 ms of log, 5 ms played) after the last frame.
  clock.advance_us(4'999);
  ASSERT_FALSE(bus.receive(got));
  clock.advance_us(1);
  ASSERT_TRUE(bus.receive(got));
  EXPECT_EQ(got.frame.data[0], 1);
  EXPECT_FALSE(bus.finished());

  EXPECT_THROW(ReplayBus({}, clock), std::invalid_argument);
  EXPECT_THROW(ReplayBus(records, clock, {.speed = 0.0}), std::invalid_argument);
  // A log spanning no time would start a new pass on every receive().
  EXPECT_THROW(ReplayBus({records[0]}, clock, {.loop = true}), std::invalid_argument);
  auto backwards = records;
  std::swap(backwards[0], backwards[1]);
  EXPECT_THROW(ReplayBus(backwards, clock), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::drivers::can_replay
