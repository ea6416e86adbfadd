#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ultrasim::render {

// What the kernel says about one display output, reduced to what choosing one needs (so the
// choice is tested without a display; render/kms_display fills these from libdrm).
struct KmsMode {
  int width_px = 0;
  int height_px = 0;
  int refresh_hz = 0;
  bool preferred = false;  // the display's native mode (DRM_MODE_TYPE_PREFERRED)
  int index = 0;           // its place in the connector's list, to fetch it back
};

struct KmsConnector {
  std::uint32_t id = 0;
  std::string name;  // as the kernel names outputs: "HDMI-A-1", "DP-2", "Virtual-1"
  bool connected = false;
  std::vector<KmsMode> modes;
};

// [display] kms_connector / kms_mode: empty connector = the first connected one; mode 0 × 0 =
// the preferred one (else the largest), refresh 0 = the highest offered at that size.
struct KmsRequest {
  std::string connector;
  int width_px = 0;
  int height_px = 0;
  int refresh_hz = 0;
};

struct KmsChoice {
  std::size_t connector = 0;  // index into the list given
  KmsMode mode;
};

// Chooses the output and its mode. Throws std::runtime_error with a line naming what was asked
// and what there is ("connector HDMI-A-2 not found; outputs: HDMI-A-1 (connected), DP-1") when
// nothing fits.
KmsChoice choose_kms_output(const std::vector<KmsConnector>& connectors, const KmsRequest& request);

// The buffers a page-flipped display cycles through, as the kernel holds them: the one on
// screen, and at most one flip queued. A buffer may be drawn into again only once the flip that
// replaced it on screen has completed (vblank). Pure bookkeeping; KmsDisplay keeps one.
class FlipQueue {
 public:
  // A flip to `buffer` was queued. False (and nothing changes) while another is pending: the
  // caller must wait for its completion first.
  bool queue(std::uintptr_t buffer);
  // The pending flip completed: its buffer is on screen. Returns the buffer it replaced (now
  // free to draw into again), or 0 when none (the first flip).
  std::uintptr_t complete();
  bool pending() const { return pending_ != 0; }
  std::uintptr_t on_screen() const { return on_screen_; }
  std::int64_t flips() const { return flips_; }

 private:
  std::uintptr_t on_screen_ = 0;
  std::uintptr_t pending_ = 0;
  std::int64_t flips_ = 0;
};

}  // namespace ultrasim::render
