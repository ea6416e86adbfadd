#pragma once

#include <stdexcept>
#include <string>

namespace ultrasim::config {

// Where a configuration value is wrong and why. line and column are 1-based; 0 means "the whole
// file" (it could not be read at all).
struct ConfigErrorDetails {
  std::string file;     // the source name given to the loader (usually the path)
  int line = 0;         // 1-based; 0: not tied to a line
  int column = 0;       // 1-based; 0: not tied to a column
  std::string key;      // dotted key, e.g. "bscan.gain_db" or "materials[2].label"; empty: none
  std::string problem;  // what is wrong, e.g. "out of range: 90"
  std::string allowed;  // the accepted range or values; empty when there is nothing to list
};

// Thrown by every loader in this module. what() is exactly one line, in the form compilers use so
// that editors can jump to it:
//   <file>:<line>:<column>: <dotted.key>: <problem>; allowed: <range or values>
// Parts that do not apply are left out (no key for TOML syntax errors, no line for unreadable
// files, no "allowed" when there is nothing to list). Constructing one allocates.
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(ConfigErrorDetails details);

  const ConfigErrorDetails& details() const noexcept { return details_; }

 private:
  ConfigErrorDetails details_;
};

// The one-line message of ConfigError for these details (newlines inside parts become spaces).
// Allocates.
std::string format_config_error(const ConfigErrorDetails& details);

}  // namespace ultrasim::config
