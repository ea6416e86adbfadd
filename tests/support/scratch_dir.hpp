#pragma once

// A fresh folder under the system temp folder for one test, removed when the test ends.
// Named after the test and the process id, so tests running in parallel never share one.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace ultrasim::testing {

class ScratchDir {
 public:
  // `tag` tells apart several scratch folders of one test.
  explicit ScratchDir(std::string_view tag = {}) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "ultrasim_" +
                       (info != nullptr ? std::string(info->test_suite_name()) + "_" + info->name()
                                        : std::string("test")) +
                       std::string(tag) + "_" + std::to_string(::getpid());
    for (char& c : name) {
      if (c == '/') c = '_';
    }
    path_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& file) const { return path_ / file; }

  // Writes text to path()/name and returns the full path.
  std::filesystem::path write(const std::string& name, std::string_view text) const {
    const std::filesystem::path file = path_ / name;
    std::ofstream(file, std::ios::binary) << text;
    return file;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace ultrasim::testing
