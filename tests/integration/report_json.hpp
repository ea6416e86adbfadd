#pragma once

// Reading the headless kiosk's report.json in the integration tests: the whole text, and numbers
// by key (the report is the kiosk's own flat JSON; a regex is enough to read it).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

namespace ultrasim::testing {

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The first number after "key": in the JSON text, from `from` on.
inline double json_number(const std::string& json, const std::string& key, std::size_t from = 0) {
  std::smatch m;
  const std::string tail = json.substr(from);
  if (!std::regex_search(tail, m, std::regex("\"" + key + "\": (-?[0-9.eE+-]+)"))) {
    ADD_FAILURE() << "no \"" << key << "\" in the report";
    return -1;
  }
  return std::stod(m[1]);
}

}  // namespace ultrasim::testing
