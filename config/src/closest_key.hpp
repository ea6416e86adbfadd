#pragma once

#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace ultrasim::config {

// The known key nearest to a misspelt one (optimal-string-alignment edit distance, so a swapped
// pair of letters counts as one edit), or nothing when none is close enough to be a likely typo.
// Allocates.
std::optional<std::string> closest_key(std::string_view unknown,
                                       std::span<const std::string> known);

}  // namespace ultrasim::config
