#include "toml_document.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <system_error>
#include <utility>

#include "ultrasim/config/config_error.hpp"

namespace ultrasim::config {
namespace {

[[noreturn]] void fail_file(const std::filesystem::path& path, std::string problem) {
  ConfigErrorDetails details;
  details.file = path.string();
  details.problem = std::move(problem);
  throw ConfigError(std::move(details));
}

}  // namespace

std::string read_text_file(const std::filesystem::path& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) fail_file(path, "cannot read file: file not found");
  if (std::filesystem::is_directory(status)) fail_file(path, "cannot read file: is a directory");
  std::ifstream stream(path, std::ios::binary);
  if (!stream) fail_file(path, std::string("cannot read file: ") + std::strerror(errno));
  std::string text((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  if (stream.bad()) fail_file(path, "cannot read file: read error");
  return text;
}

toml::table parse_toml(std::string_view text, std::string_view source_name) {
  try {
    return toml::parse(text, source_name);
  } catch (const toml::parse_error& error) {
    const toml::source_region& where = error.source();
    ConfigErrorDetails details;
    details.file = std::string(source_name);
    details.line = static_cast<int>(where.begin.line);
    details.column = static_cast<int>(where.begin.column);
    details.problem = "TOML syntax error: " + std::string(error.description());
    throw ConfigError(std::move(details));
  }
}

}  // namespace ultrasim::config
