#pragma once

#include <filesystem>
#include <string>

namespace ultrasim::config {

// What a value reader needs besides the TOML node: the name to put in error messages and the
// folder that relative paths are resolved against.
struct ReadContext {
  std::string source_name;
  std::filesystem::path base_dir;
};

// What a value writer needs: the folder that paths are written relative to.
struct WriteContext {
  std::filesystem::path base_dir;
};

}  // namespace ultrasim::config
