#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <string_view>

#include "scratch_dir.hpp"
#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config::testing {

using ::ultrasim::testing::ScratchDir;

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
