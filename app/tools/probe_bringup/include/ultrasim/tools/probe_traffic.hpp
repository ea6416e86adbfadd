#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/probe_can/sequence_tracker.hpp"
#include "ultrasim/hal/can_bus.hpp"

namespace ultrasim::tools {

// What a bring-up engineer asks of a probe's CAN traffic: per message, how many frames, at what
// rate, how regularly (arrival intervals), how many went missing by their sequence counters; and
// how many frames did not decode, by reason.
class ProbeTraffic {
 public:
  struct MessageStats {
    std::int64_t frames = 0;
    std::int64_t missed = 0;      // by the sequence counter
    std::int64_t duplicates = 0;  // the same sequence twice in a row
    std::vector<std::int64_t> intervals_us;
    hal::TimestampUs first_us = 0, last_us = 0;

    double rate_hz() const;
    // The interval at quantile q in [0, 1] (nearest rank), µs; 0 without two frames.
    std::int64_t interval_quantile_us(double q) const;
  };

  // Decodes and accounts one received frame; returns what the codec made of it.
  std::expected<drivers::probe_can::ProbeMessage, drivers::probe_can::DecodeError> add(
      const hal::ReceivedCanFrame& received);

  const std::map<std::uint32_t, MessageStats>& by_id() const { return by_id_; }
  // Frames refused, by reason (indexed by DecodeError).
  const std::array<std::int64_t, 6>& errors() const { return errors_; }
  std::int64_t frames() const { return frames_; }

  // The summary as one JSON object.
  std::string json() const;

 private:
  drivers::probe_can::ProbeCodec codec_;
  drivers::probe_can::SequenceTracker sequences_;
  std::map<std::uint32_t, MessageStats> by_id_;
  std::array<std::int64_t, 6> errors_{};
  std::int64_t frames_ = 0;
};

// One decoded message as a JSON object (the frame's time and identifier included).
std::string message_json(const hal::ReceivedCanFrame& received,
                         const drivers::probe_can::ProbeMessage& message);

}  // namespace ultrasim::tools
