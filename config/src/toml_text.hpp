#pragma once

#include <string>
#include <string_view>

namespace ultrasim::config {

// A double as a TOML float in shortest round-trip form: parsing the text gives back exactly the
// same double. Always has a '.' or an exponent, so TOML never reads it as an integer. Allocates.
std::string toml_real(double value);

// A double for people (messages, ranges): shortest round-trip form, no forced ".0". Allocates.
std::string plain_real(double value);

// A TOML basic string literal, quoted and escaped. Allocates.
std::string toml_string(std::string_view text);

}  // namespace ultrasim::config
