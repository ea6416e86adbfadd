#include "ultrasim/config/config_error.hpp"

#include <utility>

namespace ultrasim::config {
namespace {

// Messages are one line by contract; a stray newline (e.g. from a TOML library description or a
// file name) would split one error across lines in logs.
std::string one_line(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

}  // namespace

std::string format_config_error(const ConfigErrorDetails& details) {
  std::string message = details.file;
  if (details.line > 0) {
    message += ':' + std::to_string(details.line);
    if (details.column > 0) message += ':' + std::to_string(details.column);
  }
  message += ": ";
  if (!details.key.empty()) message += details.key + ": ";
  message += details.problem;
  if (!details.allowed.empty()) message += "; allowed: " + details.allowed;
  return one_line(std::move(message));
}

ConfigError::ConfigError(ConfigErrorDetails details)
    : std::runtime_error(format_config_error(details)), details_(std::move(details)) {}

}  // namespace ultrasim::config
