#pragma once

// The trainer's settings dialog (render::TrainerUi) over app.toml's simulation tables: which
// numbers it offers, and its Apply checked by the config schema itself, so the dialog accepts
// exactly what app.toml would.

#include <span>
#include <string>
#include <variant>
#include <vector>

#include "ultrasim/config/app_settings.hpp"
#include "ultrasim/render/trainer_ui.hpp"

namespace ultrasim::kiosk {

// The dialog's fields (FEM, MSDS and simulation pages: the methods' iterations and steps, the
// MSDS's springs, the collider, the stitching's seams and selection) with the values in
// `settings`. Not the [frame] budgets: the frame loop's task table is fixed when it starts.
// Allocates.
std::vector<render::SettingField> settings_fields(const config::AppSettings& settings);

// `settings` with the dialog's `values` (settings_fields order), validated by writing them as
// app.toml text and reading that back: the new settings, or the schema's refusal naming the key,
// what is wrong and what is allowed ("msds.time_step_s: out of range: -0.001; allowed: > 0").
// Allocates.
std::variant<config::AppSettings, std::string> apply_settings_fields(
    const config::AppSettings& settings, std::span<const double> values);

}  // namespace ultrasim::kiosk
