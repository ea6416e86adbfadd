#include "ultrasim/render/kms_selection.hpp"

#include <algorithm>
#include <stdexcept>

namespace ultrasim::render {

namespace {

std::string describe_outputs(const std::vector<KmsConnector>& connectors) {
  std::string text;
  for (const auto& c : connectors) {
    if (!text.empty()) text += ", ";
    text += c.name + (c.connected ? " (connected)" : "");
  }
  return text.empty() ? "none" : text;
}

std::string describe_mode(int w, int h, int hz) {
  std::string text = std::to_string(w) + "x" + std::to_string(h);
  if (hz > 0) text += "@" + std::to_string(hz);
  return text;
}

}  // namespace

KmsChoice choose_kms_output(const std::vector<KmsConnector>& connectors,
                            const KmsRequest& request) {
  std::size_t index = connectors.size();
  for (std::size_t i = 0; i < connectors.size() && index == connectors.size(); ++i) {
    const bool named = !request.connector.empty();
    if (named ? connectors[i].name == request.connector : connectors[i].connected) index = i;
  }
  if (index == connectors.size()) {
    throw std::runtime_error((request.connector.empty()
                                  ? std::string("no connected display")
                                  : "connector " + request.connector + " not found") +
                             "; outputs: " + describe_outputs(connectors));
  }
  const KmsConnector& c = connectors[index];
  if (!c.connected) throw std::runtime_error("connector " + c.name + " has no display connected");
  if (c.modes.empty()) throw std::runtime_error("connector " + c.name + " offers no mode");

  const KmsMode* best = nullptr;
  const auto area = [](const KmsMode& m) { return static_cast<long>(m.width_px) * m.height_px; };
  for (const auto& m : c.modes) {
    if (request.width_px > 0 &&
        (m.width_px != request.width_px || m.height_px != request.height_px)) {
      continue;
    }
    if (request.refresh_hz > 0 && m.refresh_hz != request.refresh_hz) continue;
    if (best == nullptr) {
      best = &m;
      continue;
    }
    if (request.width_px == 0) {
      // The native mode first, then the largest, then the fastest.
      if (m.preferred != best->preferred) {
        if (m.preferred) best = &m;
        continue;
      }
      if (area(m) != area(*best)) {
        if (area(m) > area(*best)) best = &m;
        continue;
      }
    }
    if (m.refresh_hz > best->refresh_hz) best = &m;
  }
  if (best == nullptr) {
    std::string offered;
    for (const auto& m : c.modes) {
      if (!offered.empty()) offered += ", ";
      offered += describe_mode(m.width_px, m.height_px, m.refresh_hz);
    }
    throw std::runtime_error(
        "mode " + describe_mode(request.width_px, request.height_px, request.refresh_hz) +
        " not offered by " + c.name + "; offered: " + offered);
  }
  return {index, *best};
}

bool FlipQueue::queue(std::uintptr_t buffer) {
  if (pending_ != 0) return false;
  pending_ = buffer;
  return true;
}

std::uintptr_t FlipQueue::complete() {
  if (pending_ == 0) return 0;
  const std::uintptr_t replaced = on_screen_;
  on_screen_ = pending_;
  pending_ = 0;
  ++flips_;
  return replaced;
}

}  // namespace ultrasim::render
