#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "ultrasim/hal/probe_source_settings.hpp"
#include "ultrasim/imaging/settings.hpp"
#include "ultrasim/render/settings.hpp"
#include "ultrasim/sched/settings.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::config {

// Everything the kiosk reads from app.toml, one member per TOML table. Default-constructed, it
// holds each module's own defaults (the Settings structs' member initialisers), which is also what
// an empty app.toml gives.
struct AppSettings {
  render::DisplaySettings display;         // [display]
  imaging::BscanSettings bscan;            // [bscan]
  sim::SimSettings sim;                    // [sim]
  sim::FemSettings fem;                    // [fem]
  sim::ExactFemSettings exact;             // [exact]
  sim::CorotationalSettings corotational;  // [corotational]
  sim::HyperelasticSettings hyperelastic;  // [hyperelastic]
  sim::MsdsSettings msds;                  // [msds]
  // [stitching]: how stitched cases run; the split itself (sub_volumes, overlap_nodes) is the
  // case's ([mesh] in case.toml) and is not read here.
  sim::StitchingSettings stitching;
  sim::ProbeColliderSettings collider;  // [collider]
  sched::FrameBudgetSettings frame;     // [frame]
  hal::ProbeSourceSettings probe;       // [probe]
};

// Reads and validates the app settings file at path. Every key is optional (missing keys keep the
// defaults); unknown keys and tables, wrong types and out-of-range values are errors. Returns a
// complete struct or throws ConfigError (also when the file cannot be read). Allocates; safe to
// call from any thread.
AppSettings load_app_settings(const std::filesystem::path& path);

// As load_app_settings, from TOML text already in memory; source_name is used in error messages
// only. Allocates; safe to call from any thread.
AppSettings parse_app_settings(std::string_view toml_text, std::string_view source_name);

// The TOML text for these settings: every table and key, each preceded by a one-line comment saying
// what it does and what values it accepts. parse_app_settings() of the result gives back the same
// values (doubles are written in shortest round-trip form). Allocates.
std::string format_app_toml(const AppSettings& settings);

// format_app_toml(AppSettings{}): the commented default file, kept in config/default/app.toml.
// Allocates.
std::string default_app_toml();

}  // namespace ultrasim::config
