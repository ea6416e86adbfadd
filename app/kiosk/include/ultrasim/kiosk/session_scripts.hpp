#pragma once

// The headless runs' scripted sessions over a case's scan line (the soak's random one is in
// soak_script.hpp). Each allocates.

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/kiosk/script.hpp"

namespace ultrasim::kiosk {

// sweep-press: the probe sweeps the scan line and presses, then freeze, a press while frozen
// and a deeper image; the trainee saves at the press.
Script sweep_press_session(const config::CaseScan& scan, double depth_mm);

// compare-methods: a press held while the session switches through every live method.
Script compare_methods_session(const config::CaseScan& scan);

// trainer: the probe rests over the vessels while scripted touches work every on-screen control
// (compression, freeze, calipers, save, gain, depth, method, orbit, skin, settings, service).
Script trainer_session(const config::CaseScan& scan);

}  // namespace ultrasim::kiosk
