#pragma once

// Private to app/imaging: the text header of a MetaImage file and the checks shared by the volume
// and tracked-sequence readers. Every error goes through MetaHeader::fail so each message names
// the file, the header line and the field.

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace ultrasim::imaging::detail {

// One `Key = Value` line. `value` has surrounding blanks removed (PLUS pads CompressedDataSize).
struct HeaderField {
  std::string key;
  std::string value;
  int line = 0;  // 1-based line number in the file
};

class MetaHeader {
 public:
  // Parses the header lines of `file_bytes` (the whole file) up to and including the
  // ElementDataFile line, after which the element data (or nothing, for .mhd) follows.
  // Throws MetaImageError on a line that is not `Key = Value`, a repeated key, or a header that
  // never reaches ElementDataFile. Allocates.
  static MetaHeader parse(const std::filesystem::path& path, std::string_view file_bytes);

  const std::filesystem::path& path() const { return path_; }
  const std::vector<HeaderField>& fields() const { return fields_; }
  // Byte offset of the first byte after the ElementDataFile line.
  std::size_t data_offset() const { return data_offset_; }
  // The ElementDataFile field; the last header line.
  const HeaderField& data_file_field() const { return fields_.back(); }

  // The field named `key` (exact, case-sensitive as MetaIO), or nullptr.
  const HeaderField* find(std::string_view key) const;
  // The first of `keys` that is present (synonyms such as Offset/Position/Origin), or nullptr.
  const HeaderField* find_any(std::initializer_list<std::string_view> keys) const;
  // The field named `key`; throws "<file>:<last line>: <key>: required field missing".
  const HeaderField& require(std::string_view key) const;

  // Value parsers; each throws naming the field's line and key on malformed input.
  std::vector<double> numbers(const HeaderField& field, std::size_t count) const;
  std::vector<long long> integers(const HeaderField& field, std::size_t count) const;
  bool boolean(const HeaderField& field) const;

  // Throws MetaImageError "<file>:<line>: <field>: <message>" (line omitted when 0).
  [[noreturn]] void fail(int line, std::string_view field, std::string_view message) const;
  [[noreturn]] void fail(const HeaderField& field, std::string_view message) const {
    fail(field.line, field.key, message);
  }

 private:
  std::filesystem::path path_;
  std::vector<HeaderField> fields_;
  std::size_t data_offset_ = 0;
};

// Throws MetaImageError "<file>: <message>" for failures that belong to no header line
// (cannot open, cannot write).
[[noreturn]] void fail_file(const std::filesystem::path& path, std::string_view message);

// Reads a whole file into memory; throws MetaImageError when it cannot be opened or read.
std::string read_file_bytes(const std::filesystem::path& path);

}  // namespace ultrasim::imaging::detail
