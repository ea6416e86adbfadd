#include "scalar_codecs.hpp"

#include <cmath>

namespace ultrasim::config {

bool RealIn::contains(double value) const {
  // Written so that NaN fails every comparison and is rejected.
  if (!std::isfinite(value)) return false;
  const bool above = lower == Bound::kClosed ? value >= min : value > min;
  const bool below = upper == Bound::kClosed ? value <= max : value < max;
  return above && below;
}

std::string RealIn::allowed() const {
  if (std::isinf(min) && std::isinf(max)) return "finite number";
  return std::string("number in ") + (lower == Bound::kClosed ? "[" : "(") + plain_real(min) +
         ", " + plain_real(max) + (upper == Bound::kClosed ? "]" : ")");
}

double RealIn::read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
  double value = 0.0;
  if (const auto* real = node.as_floating_point()) {
    value = real->get();
  } else if (const auto* integer = node.as_integer()) {
    value = static_cast<double>(integer->get());
  } else {
    fail_wrong_type(ctx, node, key, "number", allowed());
  }
  if (!contains(value))
    fail_at(ctx, node.source(), key, "out of range: " + toml_real(value), allowed());
  return value;
}

std::string Text::read(const toml::node& node, const ReadContext& ctx, std::string_view key) const {
  const auto* text = node.as_string();
  if (text == nullptr) fail_wrong_type(ctx, node, key, "string", allowed());
  if (non_empty && text->get().empty()) fail_at(ctx, node.source(), key, "empty", allowed());
  return text->get();
}

}  // namespace ultrasim::config
