#include "ultrasim/kiosk/settings_dialog.hpp"

#include <cmath>
#include <limits>

#include "ultrasim/config/config_error.hpp"

namespace ultrasim::kiosk {
namespace {

// One editable number: where it lives in AppSettings and how the dialog steps it.
struct Field {
  const char* tab;
  const char* table;
  const char* key;
  double step;
  double (*get)(const config::AppSettings&);
  void (*set)(config::AppSettings&, double);
  bool integer;
};

// Integers are set as entered when whole; a fraction becomes a value the schema refuses rather
// than being rounded quietly.
int to_int(double v) {
  if (!std::isfinite(v) || std::trunc(v) != v || std::abs(v) > 1e9) {
    return std::numeric_limits<int>::min();
  }
  return static_cast<int>(v);
}

#define ULTRASIM_REAL(tab, table, member, key, step)                                    \
  Field {                                                                               \
    tab, #table, #key, step,                                                            \
        [](const config::AppSettings& s) { return static_cast<double>(s.member.key); }, \
        [](config::AppSettings& s, double v) { s.member.key = v; }, false               \
  }
#define ULTRASIM_INT(tab, table, member, key, step)                                     \
  Field {                                                                               \
    tab, #table, #key, step,                                                            \
        [](const config::AppSettings& s) { return static_cast<double>(s.member.key); }, \
        [](config::AppSettings& s, double v) { s.member.key = to_int(v); }, true        \
  }

const Field kFields[] = {
    ULTRASIM_INT("FEM", fem, fem, pcg_iterations_per_frame, 5),
    ULTRASIM_INT("FEM", exact, exact, max_contact_rounds, 1),
    ULTRASIM_INT("FEM", exact, exact, max_cached_nodes, 32),
    ULTRASIM_INT("FEM", corotational, corotational, pcg_iterations_per_frame, 5),
    ULTRASIM_REAL("MSDS", msds, msds, stiffness_per_modulus_mm, 0.25),
    ULTRASIM_REAL("MSDS", msds, msds, damping_per_stiffness_s, 0.05),
    ULTRASIM_REAL("MSDS", msds, msds, time_step_s, 0.001),
    ULTRASIM_INT("MSDS", msds, msds, steps_per_frame, 1),
    ULTRASIM_INT("MSDS", msds, msds, implicit_steps_per_frame, 1),
    ULTRASIM_REAL("SIMULATION", collider, collider, radius_mm, 5.0),
    ULTRASIM_REAL("SIMULATION", stitching, stitching, spring_stiffness_per_modulus_mm, 5.0),
    ULTRASIM_REAL("SIMULATION", stitching, stitching, sleep_force_mn, 0.05),
    ULTRASIM_INT("SIMULATION", stitching, stitching, extra_sub_volumes_per_frame, 1),
};

#undef ULTRASIM_REAL
#undef ULTRASIM_INT

}  // namespace

std::vector<render::SettingField> settings_fields(const config::AppSettings& settings) {
  std::vector<render::SettingField> fields;
  for (const Field& f : kFields) {
    fields.push_back({f.tab, f.table, f.key, f.get(settings), f.step, f.integer});
  }
  return fields;
}

std::variant<config::AppSettings, std::string> apply_settings_fields(
    const config::AppSettings& settings, std::span<const double> values) {
  if (values.size() != std::size(kFields)) {
    return std::string("the dialog sent ") + std::to_string(values.size()) + " values for " +
           std::to_string(std::size(kFields)) + " fields";
  }
  config::AppSettings edited = settings;
  for (std::size_t i = 0; i < values.size(); ++i) kFields[i].set(edited, values[i]);
  try {
    return config::parse_app_settings(config::format_app_toml(edited), "settings dialog");
  } catch (const config::ConfigError& e) {
    // The key and the rule, not the line of text the check was made on (the user never saw it).
    const config::ConfigErrorDetails& d = e.details();
    std::string message = d.key.empty() ? std::string(e.what()) : d.key + ": " + d.problem;
    if (!d.key.empty() && !d.allowed.empty()) message += "; allowed: " + d.allowed;
    return message;
  }
}

}  // namespace ultrasim::kiosk
