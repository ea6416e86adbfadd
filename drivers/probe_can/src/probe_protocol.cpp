#include "ultrasim/drivers/probe_can/probe_protocol.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "probe_dbc_text.hpp"  // generated from probe.dbc

namespace ultrasim::drivers::probe_can {

namespace {

constexpr int kMessageBytes = 8;

const DbcMessage& need_message(const DbcDatabase& db, std::uint32_t id, std::string_view name) {
  const DbcMessage* m = db.message(id);
  if (m == nullptr || m->name != name) {
    throw std::invalid_argument("probe CAN database: no message " + std::string(name) + " (id " +
                                std::to_string(id) + ")");
  }
  if (m->length_bytes != kMessageBytes) {
    throw std::invalid_argument("probe CAN database: message " + std::string(name) +
                                " must be 8 bytes long");
  }
  return *m;
}

DbcSignal need_signal(const DbcMessage& m, std::string_view name) {
  const DbcSignal* s = m.signal(name);
  if (s == nullptr) {
    throw std::invalid_argument("probe CAN database: message " + m.name + " has no signal " +
                                std::string(name));
  }
  return *s;
}

double read(const DbcSignal& s, std::span<const std::uint8_t> data) {
  return to_physical(s, read_raw(s, data));
}

// Writes a physical value clamped to the signal's declared range ([0|0]: none declared).
void write(const DbcSignal& s, double value, std::span<std::uint8_t> data) {
  const bool ranged = s.minimum < s.maximum;
  const double clamped = ranged ? std::clamp(value, s.minimum, s.maximum) : value;
  write_raw(s, to_raw(s, clamped).value_or(0), data);
}

}  // namespace

struct ProbeCodec::Layout {
  struct Trailer {
    DbcSignal sequence;
    DbcSignal checksum;
  };
  struct {
    Trailer trailer;
    DbcSignal firmware_major, firmware_minor, calibration_system, calibration_gyro,
        calibration_accel, calibration_mag, error_flags, rate;
  } status;
  struct {
    Trailer trailer;
    DbcSignal a, b, c, largest;
  } orientation;
  struct {
    Trailer trailer;
    DbcSignal freeze, save, depth_up, depth_down, gain_up, gain_down, force;
  } input;
  struct {
    Trailer trailer;
    DbcSignal command, rate;
  } command;
};

std::string_view describe(DecodeError error) {
  switch (error) {
    case DecodeError::kUnknownId:
      return "unknown identifier";
    case DecodeError::kNotAProtocolFrame:
      return "extended or remote frame";
    case DecodeError::kWrongLength:
      return "wrong data length";
    case DecodeError::kBadChecksum:
      return "checksum mismatch";
    case DecodeError::kNonUnitQuaternion:
      return "orientation is not a unit quaternion";
    case DecodeError::kBadValue:
      return "value out of range";
  }
  return "unknown error";
}

std::uint8_t crc8_sae_j1850(std::span<const std::uint8_t> bytes) {
  std::uint8_t crc = 0xFF;
  for (std::uint8_t b : bytes) {
    crc ^= b;
    for (int i = 0; i < 8; ++i) {
      crc = static_cast<std::uint8_t>((crc & 0x80) != 0 ? (crc << 1) ^ 0x1D : crc << 1);
    }
  }
  return static_cast<std::uint8_t>(crc ^ 0xFF);
}

std::uint8_t probe_checksum(std::uint32_t id, std::span<const std::uint8_t> data) {
  std::array<std::uint8_t, 9> bytes{static_cast<std::uint8_t>(id & 0xFF),
                                    static_cast<std::uint8_t>((id >> 8) & 0xFF)};
  std::copy_n(data.begin(), 7, bytes.begin() + 2);
  return crc8_sae_j1850(bytes);
}

std::string_view probe_dbc_text() {
  return kProbeDbcText;
}

ProbeCodec::ProbeCodec() : ProbeCodec(parse_dbc(kProbeDbcText, "probe.dbc (built in)")) {}

ProbeCodec::ProbeCodec(DbcDatabase database) : db_(std::move(database)) {
  auto layout = std::make_shared<Layout>();
  Layout& l = *layout;
  auto trailer = [](const DbcMessage& m) {
    return Layout::Trailer{need_signal(m, "Sequence"), need_signal(m, "Checksum")};
  };
  const DbcMessage& status = need_message(db_, kStatusId, "ProbeStatus");
  l.status = {trailer(status),
              need_signal(status, "FirmwareMajor"),
              need_signal(status, "FirmwareMinor"),
              need_signal(status, "CalibrationSystem"),
              need_signal(status, "CalibrationGyro"),
              need_signal(status, "CalibrationAccel"),
              need_signal(status, "CalibrationMag"),
              need_signal(status, "ErrorFlags"),
              need_signal(status, "OrientationRateHz")};
  const DbcMessage& orientation = need_message(db_, kOrientationId, "ProbeOrientation");
  l.orientation = {trailer(orientation), need_signal(orientation, "QuatA"),
                   need_signal(orientation, "QuatB"), need_signal(orientation, "QuatC"),
                   need_signal(orientation, "QuatLargest")};
  const DbcMessage& input = need_message(db_, kInputId, "ProbeInput");
  l.input = {trailer(input),
             need_signal(input, "ButtonFreeze"),
             need_signal(input, "ButtonSave"),
             need_signal(input, "ButtonDepthUp"),
             need_signal(input, "ButtonDepthDown"),
             need_signal(input, "ButtonGainUp"),
             need_signal(input, "ButtonGainDown"),
             need_signal(input, "CompressionForce")};
  const DbcMessage& command = need_message(db_, kHostCommandId, "HostCommand");
  l.command = {trailer(command), need_signal(command, "Command"),
               need_signal(command, "OrientationRateHz")};
  for (const auto* t :
       {&l.status.trailer, &l.orientation.trailer, &l.input.trailer, &l.command.trailer}) {
    if (t->checksum.start_bit != 56 || t->checksum.length_bits != 8) {
      throw std::invalid_argument("probe CAN database: Checksum must be byte 7 of every message");
    }
  }
  layout_ = std::move(layout);
}

std::expected<ProbeMessage, DecodeError> ProbeCodec::decode(const hal::CanFrame& frame) const {
  if (frame.extended || frame.remote) return std::unexpected(DecodeError::kNotAProtocolFrame);
  if (frame.id != kStatusId && frame.id != kOrientationId && frame.id != kInputId &&
      frame.id != kHostCommandId) {
    return std::unexpected(DecodeError::kUnknownId);
  }
  if (frame.length != kMessageBytes) return std::unexpected(DecodeError::kWrongLength);
  const std::span<const std::uint8_t> data(frame.data);
  if (probe_checksum(frame.id, data) != data[7]) return std::unexpected(DecodeError::kBadChecksum);
  const Layout& l = *layout_;
  auto sequence = [&](const Layout::Trailer& t) {
    return static_cast<std::uint8_t>(read_raw(t.sequence, data));
  };
  switch (frame.id) {
    case kOrientationId: {
      // Smallest three: the left-out component is the largest and positive (probe.dbc).
      const std::array<double, 3> sent{read(l.orientation.a, data), read(l.orientation.b, data),
                                       read(l.orientation.c, data)};
      double sum_squares = 0.0, largest_sent = 0.0;
      for (double v : sent) {
        sum_squares += v * v;
        largest_sent = std::max(largest_sent, std::abs(v));
      }
      // The raw values' rounding (2e-5 each) may take a unit quaternion's three just past 1.
      if (sum_squares > 1.0 + 1e-3) return std::unexpected(DecodeError::kNonUnitQuaternion);
      const double left_out = std::sqrt(std::max(0.0, 1.0 - sum_squares));
      // The left-out component was the largest: a frame where it is not is no such quaternion.
      if (left_out < largest_sent - 1e-3) {
        return std::unexpected(DecodeError::kNonUnitQuaternion);
      }
      const auto index = static_cast<int>(read_raw(l.orientation.largest, data));
      std::array<double, 4> wxyz{};
      for (int i = 0, k = 0; i < 4; ++i) wxyz[i] = i == index ? left_out : sent[k++];
      ProbeOrientation o;
      o.orientation = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized();
      o.sequence = sequence(l.orientation.trailer);
      return o;
    }
    case kStatusId: {
      ProbeStatus s;
      s.firmware_major = static_cast<int>(read_raw(l.status.firmware_major, data));
      s.firmware_minor = static_cast<int>(read_raw(l.status.firmware_minor, data));
      s.calibration_system = static_cast<int>(read_raw(l.status.calibration_system, data));
      s.calibration_gyro = static_cast<int>(read_raw(l.status.calibration_gyro, data));
      s.calibration_accel = static_cast<int>(read_raw(l.status.calibration_accel, data));
      s.calibration_mag = static_cast<int>(read_raw(l.status.calibration_mag, data));
      s.error_flags = static_cast<std::uint16_t>(read_raw(l.status.error_flags, data));
      s.orientation_rate_hz = static_cast<int>(std::lround(read(l.status.rate, data)));
      s.sequence = sequence(l.status.trailer);
      return s;
    }
    case kInputId: {
      ProbeInput in;
      in.freeze = read_raw(l.input.freeze, data) != 0;
      in.save = read_raw(l.input.save, data) != 0;
      in.depth_up = read_raw(l.input.depth_up, data) != 0;
      in.depth_down = read_raw(l.input.depth_down, data) != 0;
      in.gain_up = read_raw(l.input.gain_up, data) != 0;
      in.gain_down = read_raw(l.input.gain_down, data) != 0;
      in.compression_force_n = read(l.input.force, data);
      in.sequence = sequence(l.input.trailer);
      return in;
    }
    default: {  // kHostCommandId
      const auto kind = read_raw(l.command.command, data);
      if (kind < 1 || kind > 3) return std::unexpected(DecodeError::kBadValue);
      HostCommand c;
      c.command = static_cast<HostCommandKind>(kind);
      c.orientation_rate_hz = static_cast<int>(read_raw(l.command.rate, data));
      if (c.command == HostCommandKind::kSetRate &&
          (c.orientation_rate_hz < 1 || c.orientation_rate_hz > 1000)) {
        return std::unexpected(DecodeError::kBadValue);
      }
      c.sequence = sequence(l.command.trailer);
      return c;
    }
  }
}

hal::CanFrame ProbeCodec::encode(const ProbeMessage& message) const {
  const Layout& l = *layout_;
  hal::CanFrame frame;
  frame.length = kMessageBytes;
  const std::span<std::uint8_t> data(frame.data);
  const Layout::Trailer* trailer = nullptr;
  std::uint8_t sequence = 0;
  if (const auto* o = std::get_if<ProbeOrientation>(&message)) {
    frame.id = kOrientationId;
    const Eigen::Quaterniond q = o->orientation.normalized();
    std::array<double, 4> wxyz{q.w(), q.x(), q.y(), q.z()};
    int index = 0;
    for (int i = 1; i < 4; ++i) {
      if (std::abs(wxyz[i]) > std::abs(wxyz[index])) index = i;
    }
    // q and −q are the same rotation: make the left-out component positive.
    const double sign = wxyz[index] < 0.0 ? -1.0 : 1.0;
    const DbcSignal* sent[3] = {&l.orientation.a, &l.orientation.b, &l.orientation.c};
    for (int i = 0, k = 0; i < 4; ++i) {
      if (i != index) write(*sent[k++], sign * wxyz[i], data);
    }
    write_raw(l.orientation.largest, index, data);
    trailer = &l.orientation.trailer;
    sequence = o->sequence;
  } else if (const auto* s = std::get_if<ProbeStatus>(&message)) {
    frame.id = kStatusId;
    write(l.status.firmware_major, s->firmware_major, data);
    write(l.status.firmware_minor, s->firmware_minor, data);
    write(l.status.calibration_system, s->calibration_system, data);
    write(l.status.calibration_gyro, s->calibration_gyro, data);
    write(l.status.calibration_accel, s->calibration_accel, data);
    write(l.status.calibration_mag, s->calibration_mag, data);
    write(l.status.error_flags, s->error_flags, data);
    write(l.status.rate, s->orientation_rate_hz, data);
    trailer = &l.status.trailer;
    sequence = s->sequence;
  } else if (const auto* in = std::get_if<ProbeInput>(&message)) {
    frame.id = kInputId;
    write(l.input.freeze, in->freeze, data);
    write(l.input.save, in->save, data);
    write(l.input.depth_up, in->depth_up, data);
    write(l.input.depth_down, in->depth_down, data);
    write(l.input.gain_up, in->gain_up, data);
    write(l.input.gain_down, in->gain_down, data);
    write(l.input.force, in->compression_force_n, data);
    trailer = &l.input.trailer;
    sequence = in->sequence;
  } else {
    const auto& c = std::get<HostCommand>(message);
    frame.id = kHostCommandId;
    write(l.command.command, static_cast<double>(c.command), data);
    write(l.command.rate, c.orientation_rate_hz, data);
    trailer = &l.command.trailer;
    sequence = c.sequence;
  }
  write_raw(trailer->sequence, sequence, data);
  write_raw(trailer->checksum, probe_checksum(frame.id, data), data);
  return frame;
}

}  // namespace ultrasim::drivers::probe_can
