#pragma once

#include <toml++/toml.h>

#include <filesystem>
#include <string>
#include <string_view>

namespace ultrasim::config {

// The whole file as text. Throws ConfigError (no line) when it is missing, a directory or
// unreadable. Allocates.
std::string read_text_file(const std::filesystem::path& path);

// Parses TOML text; a syntax error becomes a ConfigError at toml++'s reported position. Allocates.
toml::table parse_toml(std::string_view text, std::string_view source_name);

}  // namespace ultrasim::config
