#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <string_view>

#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config::testing {

// A fresh folder under the system temp dir, removed with everything in it when destroyed.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::random_device entropy;
    path_ = std::filesystem::temp_directory_path() /
            ("ultrasim_config_" + std::string(info != nullptr ? info->name() : "test") + "_" +
             std::to_string(entropy()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

  // Writes text to path()/name and returns the full path.
  std::filesystem::path write(const std::string& name, std::string_view text) const {
    const std::filesystem::path file = path_ / name;
    std::ofstream(file, std::ios::binary) << text;
    return file;
  }

 private:
  std::filesystem::path path_;
};

// What a loader threw: the one-line message and its parts.
struct Caught {
  std::string message;
  ConfigErrorDetails details;
};

// Runs f, which must throw ConfigError; a test failure (and empty Caught) otherwise.
template <typename F>
Caught error_of(F&& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return Caught{e.what(), e.details()};
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected a ConfigError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected a ConfigError, nothing was thrown";
  return {};
}

}  // namespace ultrasim::config::testing
