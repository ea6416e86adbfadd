#pragma once

#include <toml++/toml.h>

#include <string>
#include <string_view>

#include "read_context.hpp"

namespace ultrasim::config {

// Throws ConfigError pointing at the start of `where` in the source being read. Allocates.
[[noreturn]] void fail_at(const ReadContext& ctx, const toml::source_region& where,
                          std::string_view key, std::string problem, std::string allowed);

// Throws ConfigError for a node of the wrong TOML type ("expected <expected>, got <actual>").
[[noreturn]] void fail_wrong_type(const ReadContext& ctx, const toml::node& node,
                                  std::string_view key, std::string_view expected,
                                  std::string allowed);

// The TOML spec's name of a node type, for messages ("integer", "float", "array", ...).
std::string_view toml_type_name(toml::node_type type);

}  // namespace ultrasim::config
