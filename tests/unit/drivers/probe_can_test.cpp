// The probe's CAN protocol: the DBC reader on probe.dbc and on broken files, bit packing, the
// CRC against its published check value, golden frames, round trips and bad frames.
//
// The golden frames' bytes were computed independently of this code, in Python (struct.pack of
// the layout probe.dbc documents and a bit-by-bit CRC-8/SAE-J1850).

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "ultrasim/drivers/probe_can/dbc.hpp"
#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/probe_can/sequence_tracker.hpp"

namespace ultrasim::drivers::probe_can {
namespace {

hal::CanFrame frame_of(std::uint32_t id, std::array<std::uint8_t, 8> data) {
  hal::CanFrame f;
  f.id = id;
  f.length = 8;
  f.data = data;
  return f;
}

std::string error_of(const std::string& dbc) {
  try {
    parse_dbc(dbc, "test.dbc");
  } catch (const DbcError& e) {
    return e.what();
  }
  return "(parsed)";
}

TEST(Dbc, ReadsTheBuiltInProbeDatabase) {
  const DbcDatabase db = parse_dbc(probe_dbc_text(), "probe.dbc");
  EXPECT_EQ(db.version, "ultrasim-probe 1");
  ASSERT_EQ(db.messages.size(), 4u);
  const DbcMessage* orientation = db.message("ProbeOrientation");
  ASSERT_NE(orientation, nullptr);
  EXPECT_EQ(orientation->id, 0x101u);
  EXPECT_EQ(orientation->sender, "PROBE");
  const DbcSignal* c = orientation->signal("QuatC");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->start_bit, 30);
  EXPECT_EQ(c->length_bits, 15);
  EXPECT_TRUE(c->is_signed);
  EXPECT_DOUBLE_EQ(c->factor, std::sqrt(0.5) / 16383.0);
  EXPECT_EQ(orientation->signal("QuatLargest")->value_names.at(3), "Z");
  const DbcSignal* force = db.message(0x102)->signal("CompressionForce");
  ASSERT_NE(force, nullptr);
  EXPECT_EQ(force->unit, "N");
  EXPECT_DOUBLE_EQ(force->maximum, 655.35);
  const DbcSignal* command = db.message("HostCommand")->signal("Command");
  ASSERT_NE(command, nullptr);
  EXPECT_EQ(command->value_names.at(2), "SetRate");
}

TEST(Dbc, BrokenFilesNameTheLineAndWhatIsWrong) {
  const std::string head = "VERSION \"x\"\n\nBO_ 256 M: 8 PROBE\n";
  EXPECT_EQ(error_of(head + " SG_ A : 60|16@1+ (1,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: signal A (bits 60..75) lies outside message M's 8 bytes");
  EXPECT_EQ(error_of(head + " SG_ A : 0|16@0+ (1,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: signal A is big-endian (Motorola): not supported");
  EXPECT_EQ(error_of(head + " SG_ A : 0|16@1+ (1,0) [0|1] \"\" HOST\n SG_ B : 8|8@1+ (1,0) [0|1] "
                            "\"\" HOST\n"),
            "test.dbc:5: signal B overlaps A");
  EXPECT_EQ(error_of(head + " SG_ A M : 0|8@1+ (1,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: signal A is multiplexed: not supported");
  EXPECT_EQ(error_of(head + " SG_ A : 0|8@1+ (x,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: expected a number for the factor at 'x,0) [0|1] \"'");
  EXPECT_EQ(error_of(head + "\nBO_ 256 N: 8 PROBE\n"),
            "test.dbc:5: message identifier 256 is defined twice");
  EXPECT_EQ(error_of("BO_ 4096 M: 8 PROBE\n"),
            "test.dbc:1: message identifier 4096 does not fit 11 bits");
  EXPECT_EQ(error_of(" SG_ A : 0|8@1+ (1,0) [0|1] \"\" HOST\n"), "test.dbc:1: SG_ before any BO_");
  EXPECT_EQ(error_of("CM_ \"never closed\n"), "test.dbc:2: a CM_ comment is not closed");
  EXPECT_EQ(error_of(head + " SG_ A : 0|8@1+ (1,0) [2|1] \"\" HOST\n"),
            "test.dbc:4: signal A: minimum above maximum");
  EXPECT_EQ(error_of(head + " SG_ A : 0|63@1+ (1,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: signal A: length 63 is not 1..62");
  EXPECT_EQ(error_of(head + " SG_ A : 2147483647|8@1+ (1,0) [0|1] \"\" HOST\n"),
            "test.dbc:4: signal A (bits 2147483647..2147483654) lies outside message M's 8 bytes");
  // A comment spanning lines, holding what looks like a signal line, is skipped whole.
  EXPECT_EQ(error_of("CM_ \"first line\n SG_ A : 99|99@0- (x) \";\n"), "(parsed)");
}

TEST(Dbc, ReadsWhatVectorsToolsWriteAroundTheMessages) {
  // NS_'s indented list names keywords (CM_, VAL_ ...) without being statements, and
  // VECTOR__INDEPENDENT_SIG_MSG holds signals sent in no frame.
  const DbcDatabase db = parse_dbc(
      "VERSION \"\"\n\nNS_ :\n\tNS_DESC_\n\tCM_\n\tBA_DEF_\n\tVAL_\n\nBS_:\n\nBU_: A\n\n"
      "BO_ 3221225472 VECTOR__INDEPENDENT_SIG_MSG: 0 Vector__XXX\n"
      " SG_ Orphan : 0|8@1+ (1,0) [0|0] \"\" Vector__XXX\n\n"
      "BO_ 291 Real: 2 A\n SG_ Value : 0|16@1+ (0.5,0) [0|0] \"\" Vector__XXX\n",
      "vector.dbc");
  ASSERT_EQ(db.messages.size(), 1u);
  EXPECT_EQ(db.messages[0].name, "Real");
  EXPECT_NE(db.messages[0].signal("Value"), nullptr);
}

TEST(Dbc, PacksLittleEndianSignalsBitByBit) {
  DbcSignal twelve;
  twelve.start_bit = 4;
  twelve.length_bits = 12;
  std::array<std::uint8_t, 8> data{0x0F, 0, 0, 0, 0, 0, 0, 0xFF};
  write_raw(twelve, 0xABC, data);
  EXPECT_EQ(data[0], 0xCF);  // the low nibble (another signal's bits) is kept
  EXPECT_EQ(data[1], 0xAB);
  EXPECT_EQ(read_raw(twelve, data), 0xABC);
  DbcSignal signed_twelve = twelve;
  signed_twelve.is_signed = true;
  EXPECT_EQ(read_raw(signed_twelve, data), 0xABC - 0x1000);  // sign-extended: -1348
  write_raw(signed_twelve, -1, data);
  EXPECT_EQ(data[0], 0xFF);
  EXPECT_EQ(data[1], 0xFF);
  EXPECT_EQ(read_raw(signed_twelve, data), -1);

  DbcSignal scaled;
  scaled.length_bits = 8;
  scaled.factor = 0.5;
  scaled.offset = -10;
  EXPECT_EQ(to_raw(scaled, -10.0), 0);
  EXPECT_EQ(to_raw(scaled, 117.4), 255);  // 254.8 rounds to 255
  EXPECT_EQ(to_raw(scaled, 118.0), std::nullopt);
  EXPECT_EQ(to_raw(scaled, NAN), std::nullopt);
  EXPECT_DOUBLE_EQ(to_physical(scaled, 255), 117.5);
}

TEST(ProbeProtocol, CrcMatchesItsPublishedCheckValue) {
  const std::string check = "123456789";
  EXPECT_EQ(
      crc8_sae_j1850(std::span(reinterpret_cast<const std::uint8_t*>(check.data()), check.size())),
      0x4B);
}

TEST(ProbeProtocol, GoldenFramesDecodeAndEncodeToTheSameBytes) {
  const ProbeCodec codec;
  // 30° about z, sequence 7: w left out (index 0); x = y = 0, z = round(sin 15° / (√½ / 16383))
  // = 5997 at bits 30..44.
  const hal::CanFrame orientation = frame_of(0x101, {0, 0, 0, 0x40, 0xDB, 0x05, 0x07, 0xD8});
  const auto o = codec.decode(orientation);
  ASSERT_TRUE(o.has_value()) << describe(o.error());
  const auto& po = std::get<ProbeOrientation>(*o);
  const Eigen::Quaterniond want(Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(po.orientation.angularDistance(want), 1e-4);
  EXPECT_EQ(po.sequence, 7);
  EXPECT_EQ(codec.encode(po), orientation);

  // Firmware 2.5, calibration 3/2/1/0, flags IMU-not-responding + supply-low, 200 Hz, seq 42.
  const hal::CanFrame status = frame_of(0x100, {0x02, 0x05, 0x1B, 0x09, 0x00, 0x32, 0x2A, 0xF0});
  const auto s = codec.decode(status);
  ASSERT_TRUE(s.has_value()) << describe(s.error());
  const auto& ps = std::get<ProbeStatus>(*s);
  EXPECT_EQ(ps.firmware_major, 2);
  EXPECT_EQ(ps.firmware_minor, 5);
  EXPECT_EQ(ps.calibration_system, 3);
  EXPECT_EQ(ps.calibration_gyro, 2);
  EXPECT_EQ(ps.calibration_accel, 1);
  EXPECT_EQ(ps.calibration_mag, 0);
  EXPECT_EQ(ps.error_flags, kImuNotResponding | kSupplyLow);
  EXPECT_EQ(ps.orientation_rate_hz, 200);
  EXPECT_EQ(ps.sequence, 42);
  EXPECT_EQ(codec.encode(ps), status);

  // Freeze and gain-down held, 12.34 N, seq 3.
  const hal::CanFrame input = frame_of(0x102, {0x21, 0x00, 0xD2, 0x04, 0x00, 0x00, 0x03, 0x34});
  const auto in = codec.decode(input);
  ASSERT_TRUE(in.has_value()) << describe(in.error());
  const auto& pi = std::get<ProbeInput>(*in);
  EXPECT_TRUE(pi.freeze && pi.gain_down);
  EXPECT_FALSE(pi.save || pi.depth_up || pi.depth_down || pi.gain_up);
  EXPECT_NEAR(pi.compression_force_n, 12.34, 1e-9);
  EXPECT_EQ(codec.encode(pi), input);

  // Set the rate to 250 Hz, seq 9.
  const hal::CanFrame command = frame_of(0x200, {0x02, 0xFA, 0x00, 0, 0, 0, 0x09, 0xC7});
  const auto c = codec.decode(command);
  ASSERT_TRUE(c.has_value()) << describe(c.error());
  EXPECT_EQ(std::get<HostCommand>(*c).command, HostCommandKind::kSetRate);
  EXPECT_EQ(std::get<HostCommand>(*c).orientation_rate_hz, 250);
  EXPECT_EQ(codec.encode(*c), command);
}

TEST(ProbeProtocol, OrientationsRoundTripWithinTheQuantisation) {
  const ProbeCodec codec;
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  double worst_rad = 0.0;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
    q.normalize();
    const ProbeOrientation sent{q, static_cast<std::uint8_t>(i)};
    const auto got = codec.decode(codec.encode(sent));
    ASSERT_TRUE(got.has_value()) << describe(got.error()) << " at " << i;
    const auto& o = std::get<ProbeOrientation>(*got);
    EXPECT_EQ(o.sequence, sent.sequence);
    worst_rad = std::max(worst_rad, o.orientation.angularDistance(q));
  }
  // Smallest three at 15 bits over ±1/√2: 4.3e-5 per component, a few thousandths of a degree.
  EXPECT_LT(worst_rad * 180.0 / M_PI, 0.01);
}

TEST(ProbeProtocol, BadFramesAreRefusedWithTheirReason) {
  const ProbeCodec codec;
  hal::CanFrame good = codec.encode(ProbeOrientation{});
  ASSERT_TRUE(codec.decode(good).has_value());

  hal::CanFrame flipped = good;
  flipped.data[2] ^= 0x10;
  EXPECT_EQ(codec.decode(flipped).error(), DecodeError::kBadChecksum);
  hal::CanFrame short_frame = good;
  short_frame.length = 7;
  EXPECT_EQ(codec.decode(short_frame).error(), DecodeError::kWrongLength);
  hal::CanFrame extended = good;
  extended.extended = true;
  EXPECT_EQ(codec.decode(extended).error(), DecodeError::kNotAProtocolFrame);
  hal::CanFrame other = good;
  other.id = 0x123;
  EXPECT_EQ(codec.decode(other).error(), DecodeError::kUnknownId);
  // Three components of 0.7 with a valid checksum: their squares add up past 1.
  EXPECT_EQ(codec.decode(frame_of(0x101, {0x5A, 0x3F, 0xAD, 0x9F, 0xD6, 0x0F, 0x01, 0x81})).error(),
            DecodeError::kNonUnitQuaternion);
  // 0.7, 0.7, 0 sent with w left out: w would be 0.14, not the largest.
  EXPECT_EQ(codec.decode(frame_of(0x101, {0x5A, 0x3F, 0xAD, 0x1F, 0x00, 0x00, 0x02, 0x8D})).error(),
            DecodeError::kNonUnitQuaternion);
  hal::CanFrame unknown_command = frame_of(0x200, {9, 0, 0, 0, 0, 0, 0, 0});
  unknown_command.data[7] = probe_checksum(0x200, unknown_command.data);
  EXPECT_EQ(codec.decode(unknown_command).error(), DecodeError::kBadValue);
  EXPECT_EQ(describe(DecodeError::kBadChecksum), "checksum mismatch");
}

TEST(ProbeProtocol, ADatabaseWithoutASignalTheCodecNeedsIsRefusedByName) {
  std::string dbc(probe_dbc_text());
  const std::string line =
      " SG_ QuatB : 15|15@1- (4.316100721397471E-005,0) [-0.70715|0.70711] \"\" HOST\n";
  dbc.erase(dbc.find(line), line.size());
  try {
    ProbeCodec codec(parse_dbc(dbc, "edited.dbc"));
    FAIL() << "a codec without QuatB was built";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "probe CAN database: message ProbeOrientation has no signal QuatB");
  }
}

}  // namespace
}  // namespace ultrasim::drivers::probe_can

namespace ultrasim::drivers::probe_can {
namespace {

TEST(SequenceTracker, CountsFramesMissedPerIdentifierAcrossTheWrap) {
  SequenceTracker t;
  EXPECT_EQ(t.observe(0x101, 250).missed, 0);  // first of its identifier
  EXPECT_EQ(t.observe(0x101, 251).missed, 0);
  EXPECT_EQ(t.observe(0x100, 9).missed, 0);  // another identifier counts on its own
  EXPECT_EQ(t.observe(0x101, 254).missed, 2);
  EXPECT_EQ(t.observe(0x101, 255).missed, 0);
  EXPECT_EQ(t.observe(0x101, 0).missed, 0);  // wraps
  EXPECT_EQ(t.observe(0x101, 3).missed, 2);
  const SequenceTracker::Step again = t.observe(0x101, 3);
  EXPECT_TRUE(again.duplicate);
  EXPECT_EQ(again.missed, 0);
  EXPECT_EQ(t.observe(0x100, 10).missed, 0);
  t.reset();
  EXPECT_EQ(t.observe(0x101, 100).missed, 0);
}

}  // namespace
}  // namespace ultrasim::drivers::probe_can
