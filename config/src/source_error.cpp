#include "source_error.hpp"

#include <utility>

#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config {

void fail_at(const ReadContext& ctx, const toml::source_region& where, std::string_view key,
             std::string problem, std::string allowed) {
  throw ConfigError(ConfigErrorDetails{.file = ctx.source_name,
                                       .line = static_cast<int>(where.begin.line),
                                       .column = static_cast<int>(where.begin.column),
                                       .key = std::string(key),
                                       .problem = std::move(problem),
                                       .allowed = std::move(allowed)});
}

void fail_wrong_type(const ReadContext& ctx, const toml::node& node, std::string_view key,
                     std::string_view expected, std::string allowed) {
  fail_at(ctx, node.source(), key,
          "wrong type: expected " + std::string(expected) + ", got " +
              std::string(toml_type_name(node.type())),
          std::move(allowed));
}

std::string_view toml_type_name(toml::node_type type) {
  switch (type) {
    case toml::node_type::none:
      return "nothing";
    case toml::node_type::table:
      return "table";
    case toml::node_type::array:
      return "array";
    case toml::node_type::string:
      return "string";
    case toml::node_type::integer:
      return "integer";
    case toml::node_type::floating_point:
      return "float";
    case toml::node_type::boolean:
      return "boolean";
    case toml::node_type::date:
      return "date";
    case toml::node_type::time:
      return "time";
    case toml::node_type::date_time:
      return "date-time";
  }
  return "unknown";
}

}  // namespace ultrasim::config
