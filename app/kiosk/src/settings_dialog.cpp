#include "ultrasim/kiosk/settings_dialog.hpp"

#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

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

template <typename T>
T from_dialog(double v) {
  if constexpr (std::is_integral_v<T>) {
    return to_int(v);
  } else {
    return v;
  }
}

// A field of app.toml's `table` (AppSettings has a member of the same name), whose type says
// whether it is a whole number.
#define ULTRASIM_FIELD(tab, table, key, step)                                          \
  Field {                                                                              \
    tab, #table, #key, step,                                                           \
        [](const config::AppSettings& s) { return static_cast<double>(s.table.key); }, \
        [](config::AppSettings& s, double v) {                                         \
          s.table.key = from_dialog<decltype(s.table.key)>(v);                         \
        },                                                                             \
        std::is_integral_v<decltype(std::declval<config::AppSettings&>().table.key)>   \
  }

const Field kFields[] = {
    ULTRASIM_FIELD("FEM", fem, pcg_iterations_per_frame, 5),
    ULTRASIM_FIELD("FEM", exact, max_contact_rounds, 1),
    ULTRASIM_FIELD("FEM", exact, max_cached_nodes, 32),
    ULTRASIM_FIELD("FEM", corotational, pcg_iterations_per_frame, 5),
    ULTRASIM_FIELD("MSDS", msds, stiffness_per_modulus_mm, 0.25),
    ULTRASIM_FIELD("MSDS", msds, damping_per_stiffness_s, 0.05),
    ULTRASIM_FIELD("MSDS", msds, time_step_s, 0.001),
    ULTRASIM_FIELD("MSDS", msds, steps_per_frame, 1),
    ULTRASIM_FIELD("MSDS", msds, implicit_steps_per_frame, 1),
    ULTRASIM_FIELD("SIMULATION", collider, radius_mm, 5.0),
    ULTRASIM_FIELD("SIMULATION", stitching, spring_stiffness_per_modulus_mm, 5.0),
    ULTRASIM_FIELD("SIMULATION", stitching, seam_load_rate, 0.05),
    ULTRASIM_FIELD("SIMULATION", stitching, sleep_force_mn, 0.05),
    ULTRASIM_FIELD("SIMULATION", stitching, extra_sub_volumes_per_frame, 1),
};

#undef ULTRASIM_FIELD

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
