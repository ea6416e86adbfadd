#include "ultrasim/tools/probe_traffic.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace ultrasim::tools {

namespace pc = drivers::probe_can;

namespace {

std::uint8_t sequence_of(const pc::ProbeMessage& m) {
  return std::visit([](const auto& v) { return v.sequence; }, m);
}

}  // namespace

std::string_view ProbeTraffic::message_name(std::uint32_t id) const {
  const drivers::probe_can::DbcMessage* m = codec_.database().message(id);
  return m != nullptr ? std::string_view(m->name) : std::string_view("unknown");
}

double ProbeTraffic::MessageStats::rate_hz() const {
  if (frames < 2 || last_us <= first_us) return 0.0;
  return static_cast<double>(frames - 1) * 1e6 / static_cast<double>(last_us - first_us);
}

std::int64_t ProbeTraffic::MessageStats::interval_quantile_us(double q) const {
  if (intervals_us.empty()) return 0;
  std::vector<std::int64_t> sorted = intervals_us;
  std::sort(sorted.begin(), sorted.end());
  const auto rank =
      static_cast<std::size_t>(std::clamp(std::ceil(q * static_cast<double>(sorted.size())) - 1.0,
                                          0.0, static_cast<double>(sorted.size() - 1)));
  return sorted[rank];
}

std::expected<pc::ProbeMessage, pc::DecodeError> ProbeTraffic::add(
    const hal::ReceivedCanFrame& received) {
  ++frames_;
  auto decoded = codec_.decode(received.frame);
  if (!decoded) {
    ++errors_[static_cast<std::size_t>(decoded.error())];
    return decoded;
  }
  MessageStats& s = by_id_[received.frame.id];
  if (s.frames > 0) s.intervals_us.push_back(received.timestamp_us - s.last_us);
  if (s.frames == 0) s.first_us = received.timestamp_us;
  s.last_us = received.timestamp_us;
  ++s.frames;
  const auto step = sequences_.observe(received.frame.id, sequence_of(*decoded));
  s.missed += step.missed;
  s.duplicates += step.duplicate;
  return decoded;
}

std::string ProbeTraffic::json() const {
  std::ostringstream out;
  out << "{\"frames\": " << frames_ << ", \"messages\": {";
  bool first = true;
  for (const auto& [id, s] : by_id_) {
    if (!first) out << ", ";
    first = false;
    char rate[32];
    std::snprintf(rate, sizeof rate, "%.2f", s.rate_hz());
    out << '"' << message_name(id) << "\": {\"frames\": " << s.frames << ", \"rate_hz\": " << rate
        << ", \"interval_us\": {\"p50\": " << s.interval_quantile_us(0.5)
        << ", \"p99\": " << s.interval_quantile_us(0.99)
        << ", \"max\": " << s.interval_quantile_us(1.0) << "}, \"missed\": " << s.missed
        << ", \"duplicates\": " << s.duplicates << '}';
  }
  out << "}, \"errors\": {";
  for (std::size_t e = 0; e < errors_.size(); ++e) {
    if (e > 0) out << ", ";
    out << '"' << pc::describe(static_cast<pc::DecodeError>(e)) << "\": " << errors_[e];
  }
  out << "}}";
  return out.str();
}

bool TrafficTap::receive(hal::ReceivedCanFrame& out) {
  if (!bus_.receive(out)) return false;
  const auto decoded = traffic_.add(out);
  if (callback_ != nullptr) callback_(context_, out, decoded);
  return true;
}

std::string driver_json(const pc::CanProbe& probe, const hal::CanBusStats& bus) {
  static constexpr const char* kStates[] = {"reset", "configure", "streaming", "fault"};
  static constexpr const char* kBusStates[] = {"error-active", "error-passive", "bus-off"};
  const pc::CanProbe::Perf& perf = probe.perf();
  const pc::IntervalHistogram& h = perf.orientation_intervals;
  const pc::CanProbe::Counters& c = probe.counters();
  std::ostringstream out;
  out << "{\"state\": \"" << kStates[static_cast<int>(probe.state())] << "\", \"state_us\": {";
  for (int s = 0; s < 4; ++s) {
    out << (s > 0 ? ", " : "") << '"' << kStates[s] << "\": " << perf.state_us[s];
  }
  char mean[32];
  std::snprintf(mean, sizeof mean, "%.1f", h.mean_us());
  out << "}, \"faults\": " << perf.faults << ", \"rate_requests\": " << perf.rate_requests
      << ", \"orientation_interval_us\": {\"count\": " << h.count() << ", \"min\": " << h.min_us()
      << ", \"p50\": " << h.quantile_us(0.5) << ", \"p99\": " << h.quantile_us(0.99)
      << ", \"max\": " << h.max_us() << ", \"mean\": " << mean << ", \"histogram_100us\": {";
  bool first = true;
  for (int b = 0; b < pc::IntervalHistogram::kBins; ++b) {
    if (h.bins()[static_cast<std::size_t>(b)] == 0) continue;
    out << (first ? "" : ", ") << '"' << b * pc::IntervalHistogram::kBinUs
        << "\": " << h.bins()[static_cast<std::size_t>(b)];
    first = false;
  }
  out << "}}, \"counters\": {\"frames\": " << c.frames << ", \"orientations\": " << c.orientations
      << ", \"missed\": " << c.missed << ", \"duplicates\": " << c.duplicates
      << ", \"refused\": " << c.refused << ", \"stale_events\": " << c.stale_events
      << "}, \"bus\": {\"state\": \"" << kBusStates[static_cast<int>(bus.state)]
      << "\", \"rx_frames\": " << bus.rx_frames << ", \"tx_frames\": " << bus.tx_frames
      << ", \"tx_failures\": " << bus.tx_failures << ", \"rx_overflows\": " << bus.rx_overflows
      << ", \"error_frames\": " << bus.error_frames
      << ", \"bus_off_events\": " << bus.bus_off_events << "}}";
  return out.str();
}

std::string ProbeTraffic::message_json(const hal::ReceivedCanFrame& received,
                                       const pc::ProbeMessage& message) const {
  std::ostringstream out;
  out.precision(9);
  out << "{\"t_us\": " << received.timestamp_us << ", \"message\": \""
      << message_name(received.frame.id) << "\", \"sequence\": " << int{sequence_of(message)};
  if (const auto* o = std::get_if<pc::ProbeOrientation>(&message)) {
    const auto& q = o->orientation;
    out << ", \"w\": " << q.w() << ", \"x\": " << q.x() << ", \"y\": " << q.y()
        << ", \"z\": " << q.z();
  } else if (const auto* s = std::get_if<pc::ProbeStatus>(&message)) {
    out << ", \"firmware\": \"" << s->firmware_major << '.' << s->firmware_minor
        << "\", \"calibration\": [" << s->calibration_system << ", " << s->calibration_gyro << ", "
        << s->calibration_accel << ", " << s->calibration_mag
        << "], \"error_flags\": " << s->error_flags
        << ", \"orientation_rate_hz\": " << s->orientation_rate_hz;
  } else if (const auto* in = std::get_if<pc::ProbeInput>(&message)) {
    out << ", \"buttons\": [" << in->freeze << ", " << in->save << ", " << in->depth_up << ", "
        << in->depth_down << ", " << in->gain_up << ", " << in->gain_down
        << "], \"compression_force_n\": " << in->compression_force_n;
  } else {
    const auto& c = std::get<pc::HostCommand>(message);
    out << ", \"command\": " << static_cast<int>(c.command)
        << ", \"orientation_rate_hz\": " << c.orientation_rate_hz;
  }
  out << '}';
  return out.str();
}

}  // namespace ultrasim::tools
