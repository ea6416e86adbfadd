#include "path_codec.hpp"

#include <system_error>

#include "source_error.hpp"
#include "toml_text.hpp"

namespace ultrasim::config {

std::string ExistingFile::allowed() const {
  return "path of an existing file, relative to the case folder or absolute";
}

std::filesystem::path ExistingFile::read(const toml::node& node, const ReadContext& ctx,
                                         std::string_view key) const {
  const auto* text = node.as_string();
  if (text == nullptr) fail_wrong_type(ctx, node, key, "string", allowed());
  if (text->get().empty()) fail_at(ctx, node.source(), key, "empty path", allowed());
  std::filesystem::path path(text->get());
  if (path.is_relative()) path = ctx.base_dir / path;
  path = path.lexically_normal();
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) {
    fail_at(ctx, node.source(), key, "file not found: " + path.string(), allowed());
  }
  if (!std::filesystem::is_regular_file(status)) {
    fail_at(ctx, node.source(), key, "not a regular file: " + path.string(), allowed());
  }
  return path;
}

std::string ExistingFile::write(const std::filesystem::path& value, const WriteContext& ctx) const {
  const std::filesystem::path relative = value.lexically_relative(ctx.base_dir);
  const bool inside = !relative.empty() && *relative.begin() != "..";
  return toml_string(inside && value.is_absolute() ? relative.generic_string()
                                                   : value.generic_string());
}

}  // namespace ultrasim::config
