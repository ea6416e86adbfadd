#include "ultrasim/kiosk/settings_dialog.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <variant>
#include <vector>

namespace ultrasim::kiosk {
namespace {

std::vector<double> values_of(const std::vector<render::SettingField>& fields) {
  std::vector<double> values;
  for (const auto& f : fields) values.push_back(f.value);
  return values;
}

std::size_t index_of(const std::vector<render::SettingField>& fields, std::string_view key) {
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (std::string(fields[i].table) + "." + std::string(fields[i].key) == key) return i;
  }
  ADD_FAILURE() << key << " is not in the dialog";
  return 0;
}

TEST(SettingsDialog, OffersTheFemMsdsAndSimulationNumbersWithTheirValues) {
  config::AppSettings settings;
  settings.msds.steps_per_frame = 17;
  const auto fields = settings_fields(settings);
  EXPECT_EQ(fields[index_of(fields, "msds.steps_per_frame")].value, 17.0);
  EXPECT_TRUE(fields[index_of(fields, "msds.steps_per_frame")].integer);
  for (const char* tab : {"FEM", "MSDS", "SIMULATION"}) {
    EXPECT_TRUE(std::ranges::any_of(fields, [&](const auto& f) { return f.tab == tab; })) << tab;
  }
  for (const auto& f : fields) EXPECT_GT(f.step, 0.0) << f.key;
}

TEST(SettingsDialog, AValidEditComesBackAsSettings) {
  const config::AppSettings settings;
  const auto fields = settings_fields(settings);
  auto values = values_of(fields);
  values[index_of(fields, "msds.damping_per_stiffness_s")] = 0.25;
  values[index_of(fields, "fem.pcg_iterations_per_frame")] = 30;
  const auto result = apply_settings_fields(settings, values);
  ASSERT_TRUE(std::holds_alternative<config::AppSettings>(result)) << std::get<std::string>(result);
  const auto& applied = std::get<config::AppSettings>(result);
  EXPECT_EQ(applied.msds.damping_per_stiffness_s, 0.25);
  EXPECT_EQ(applied.fem.pcg_iterations_per_frame, 30);
  EXPECT_EQ(applied.display.width_px, settings.display.width_px) << "other tables untouched";
}

// The schema's rules, not the dialog's: what app.toml refuses, the dialog refuses, in its words.
TEST(SettingsDialog, TheSchemaRefusesOutOfRangeValuesNamingTheKey) {
  const config::AppSettings settings;
  const auto fields = settings_fields(settings);
  auto values = values_of(fields);
  values[index_of(fields, "msds.time_step_s")] = -0.001;
  const auto refused = apply_settings_fields(settings, values);
  ASSERT_TRUE(std::holds_alternative<std::string>(refused));
  const std::string& message = std::get<std::string>(refused);
  EXPECT_NE(message.find("msds.time_step_s"), std::string::npos) << message;
  EXPECT_NE(message.find("allowed"), std::string::npos) << message;
  EXPECT_EQ(message.find("settings dialog:"), std::string::npos) << "no line of hidden text";

  values = values_of(fields);
  values[index_of(fields, "msds.steps_per_frame")] = 2.5;  // not a whole number of steps
  EXPECT_TRUE(std::holds_alternative<std::string>(apply_settings_fields(settings, values)));
  values = values_of(fields);
  values.pop_back();
  EXPECT_TRUE(std::holds_alternative<std::string>(apply_settings_fields(settings, values)));
}

}  // namespace
}  // namespace ultrasim::kiosk
