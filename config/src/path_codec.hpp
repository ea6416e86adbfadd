#pragma once

#include <toml++/toml.h>

#include <filesystem>
#include <string>
#include <string_view>

#include "read_context.hpp"

namespace ultrasim::config {

// A path to a file that must exist when read. Relative paths are resolved against the context's
// base_dir (the case folder), so a case folder can be moved or copied as a whole.
struct ExistingFile {
  using value_type = std::filesystem::path;

  std::string allowed() const;
  std::filesystem::path read(const toml::node& node, const ReadContext& ctx,
                             std::string_view key) const;
  // Relative to the context's base_dir when the path lies inside it; absolute otherwise.
  std::string write(const std::filesystem::path& value, const WriteContext& ctx) const;
};

}  // namespace ultrasim::config
