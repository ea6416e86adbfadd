#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/drivers/probe_can/can_probe.hpp"
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

  // One decoded message as a JSON object (the frame's time and identifier included).
  std::string message_json(const hal::ReceivedCanFrame& received,
                           const drivers::probe_can::ProbeMessage& message) const;

  // The message's name in the protocol's database ("unknown" for another identifier).
  std::string_view message_name(std::uint32_t id) const;

 private:
  drivers::probe_can::ProbeCodec codec_;
  drivers::probe_can::SequenceTracker sequences_;
  std::map<std::uint32_t, MessageStats> by_id_;
  std::array<std::int64_t, 6> errors_{};
  std::int64_t frames_ = 0;
};

// A CanBus in front of another that accounts every frame received through it in a ProbeTraffic
// (and hands it to `on_frame`, if set), so the bring-up tool sees the traffic the probe driver
// reads. Sending passes straight through.
class TrafficTap final : public hal::CanBus {
 public:
  // `bus` and `traffic` must outlive the tap.
  TrafficTap(hal::CanBus& bus, ProbeTraffic& traffic) : bus_(bus), traffic_(traffic) {}

  using FrameCallback = void (*)(void* context, const hal::ReceivedCanFrame& received,
                                 const std::expected<drivers::probe_can::ProbeMessage,
                                                     drivers::probe_can::DecodeError>& decoded);
  void on_frame(FrameCallback callback, void* context) {
    callback_ = callback;
    context_ = context;
  }

  bool send(const hal::CanFrame& frame, hal::TimestampUs deadline_us) override {
    return bus_.send(frame, deadline_us);
  }
  bool receive(hal::ReceivedCanFrame& out) override;
  hal::CanBusStats stats() const override { return bus_.stats(); }

 private:
  hal::CanBus& bus_;
  ProbeTraffic& traffic_;
  FrameCallback callback_ = nullptr;
  void* context_ = nullptr;
};

// The probe driver's view as one JSON object: its state, time in each state, faults, rate
// requests, the orientation arrival intervals (count, min, p50, p99, max, mean, and the
// histogram's non-empty 100 µs bins), its counters, and the bus's stats.
std::string driver_json(const drivers::probe_can::CanProbe& probe, const hal::CanBusStats& bus);

}  // namespace ultrasim::tools
