#pragma once

// Codecs for single TOML values. A codec reads one TOML node into a C++ value (validating type and
// range, throwing ConfigError with the node's position), writes a value back as TOML text, and
// describes what it accepts for messages and comments. Fields (table_schema.hpp) pair a codec with
// a struct member; the same codec object drives loading, error messages and the default file.

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "read_context.hpp"
#include "source_error.hpp"
#include "toml_text.hpp"

namespace ultrasim::config {

// An integer in [min, max], stored as T (int, std::int64_t).
template <typename T>
struct IntegerIn {
  using value_type = T;
  std::int64_t min = std::numeric_limits<T>::min();
  std::int64_t max = std::numeric_limits<T>::max();

  std::string allowed() const {
    return "integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  }

  T read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
    const auto* integer = node.as_integer();
    if (integer == nullptr) fail_wrong_type(ctx, node, key, "integer", allowed());
    const std::int64_t value = integer->get();
    if (value < min || value > max) {
      fail_at(ctx, node.source(), key, "out of range: " + std::to_string(value), allowed());
    }
    return static_cast<T>(value);
  }

  std::string write(T value, const WriteContext&) const { return std::to_string(value); }
};

// Whether an interval includes its end point.
enum class Bound { kClosed, kOpen };

// A finite double in an interval whose ends may be open or closed. TOML integers are accepted too
// (width_mm = 38 means 38.0); NaN and infinities never are.
struct RealIn {
  using value_type = double;
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  Bound lower = Bound::kOpen;
  Bound upper = Bound::kOpen;

  static RealIn closed(double lo, double hi) { return {lo, hi, Bound::kClosed, Bound::kClosed}; }
  static RealIn open(double lo, double hi) { return {lo, hi, Bound::kOpen, Bound::kOpen}; }
  static RealIn open_closed(double lo, double hi) { return {lo, hi, Bound::kOpen, Bound::kClosed}; }
  static RealIn closed_open(double lo, double hi) { return {lo, hi, Bound::kClosed, Bound::kOpen}; }
  static RealIn finite() { return {}; }

  bool contains(double value) const;
  std::string allowed() const;
  double read(const toml::node& node, const ReadContext& ctx, std::string_view key) const;
  std::string write(double value, const WriteContext&) const { return toml_real(value); }
};

// true or false.
struct Boolean {
  using value_type = bool;

  std::string allowed() const { return "true or false"; }
  bool read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
    const auto* flag = node.as_boolean();
    if (flag == nullptr) fail_wrong_type(ctx, node, key, "boolean", allowed());
    return flag->get();
  }
  std::string write(bool value, const WriteContext&) const { return value ? "true" : "false"; }
};

// A string; optionally it must not be empty.
struct Text {
  using value_type = std::string;
  bool non_empty = false;

  std::string allowed() const { return non_empty ? "non-empty string" : "string"; }
  std::string read(const toml::node& node, const ReadContext& ctx, std::string_view key) const;
  std::string write(const std::string& value, const WriteContext&) const {
    return toml_string(value);
  }
};

// One of a fixed set of strings, each naming an enumerator of E.
template <typename E>
struct Choice {
  using value_type = E;
  std::vector<std::pair<std::string, E>> names;

  std::string allowed() const {
    std::string text = "one of ";
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (i > 0) text += ", ";
      text += toml_string(names[i].first);
    }
    return text;
  }

  E read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
    const auto* text = node.as_string();
    if (text == nullptr) fail_wrong_type(ctx, node, key, "string", allowed());
    for (const auto& [name, value] : names) {
      if (name == text->get()) return value;
    }
    fail_at(ctx, node.source(), key, "unknown value " + toml_string(text->get()), allowed());
  }

  std::string write(E value, const WriteContext&) const {
    for (const auto& [name, candidate] : names) {
      if (candidate == value) return toml_string(name);
    }
    // A programming error (an enumerator without a name), not a configuration error.
    throw std::logic_error("config::Choice: enumerator has no name");
  }
};

}  // namespace ultrasim::config
