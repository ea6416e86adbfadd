#pragma once

// Codecs for TOML arrays, built from an element codec (see scalar_codecs.hpp for the interface).

#include <algorithm>
#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "read_context.hpp"
#include "source_error.hpp"

namespace ultrasim::config {

// "key[i]", the dotted key of one array element, for messages.
inline std::string element_key(std::string_view key, std::size_t index) {
  return std::string(key) + "[" + std::to_string(index) + "]";
}

// Exactly N elements, each read by Element (e.g. a 3D point).
template <typename Element, std::size_t N>
struct FixedArray {
  using value_type = std::array<typename Element::value_type, N>;
  Element element;

  std::string allowed() const {
    return "array of " + std::to_string(N) + ", each " + element.allowed();
  }

  value_type read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
    const auto* array = node.as_array();
    if (array == nullptr) fail_wrong_type(ctx, node, key, "array", allowed());
    if (array->size() != N) {
      fail_at(ctx, node.source(), key,
              "wrong length: " + std::to_string(array->size()) + " elements", allowed());
    }
    value_type value{};
    for (std::size_t i = 0; i < N; ++i) {
      value[i] = element.read(*array->get(i), ctx, element_key(key, i));
    }
    return value;
  }

  std::string write(const value_type& value, const WriteContext& ctx) const {
    std::string text = "[";
    for (std::size_t i = 0; i < N; ++i) {
      if (i > 0) text += ", ";
      text += element.write(value[i], ctx);
    }
    return text + "]";
  }
};

// Any number of elements, each read by Element; optionally no value may appear twice.
template <typename Element>
struct List {
  using value_type = std::vector<typename Element::value_type>;
  Element element;
  bool unique = false;

  std::string allowed() const {
    return std::string("array, each ") + element.allowed() + (unique ? ", no duplicates" : "");
  }

  value_type read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
    const auto* array = node.as_array();
    if (array == nullptr) fail_wrong_type(ctx, node, key, "array", allowed());
    value_type values;
    values.reserve(array->size());
    for (std::size_t i = 0; i < array->size(); ++i) {
      const toml::node& item = *array->get(i);
      auto value = element.read(item, ctx, element_key(key, i));
      if (unique && std::find(values.begin(), values.end(), value) != values.end()) {
        fail_at(ctx, item.source(), element_key(key, i),
                "duplicate value " + element.write(value, WriteContext{}), allowed());
      }
      values.push_back(std::move(value));
    }
    return values;
  }

  std::string write(const value_type& values, const WriteContext& ctx) const {
    std::string text = "[";
    for (std::size_t i = 0; i < values.size(); ++i) {
      if (i > 0) text += ", ";
      text += element.write(values[i], ctx);
    }
    return text + "]";
  }
};

}  // namespace ultrasim::config
