#include "metaimage_header.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <system_error>
#include <unordered_map>

#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging::detail {

namespace {

constexpr std::string_view kBlanks = " \t\r\f\v";

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(kBlanks);
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(kBlanks);
  return s.substr(first, last - first + 1);
}

std::vector<std::string_view> split_blanks(std::string_view s) {
  std::vector<std::string_view> tokens;
  std::size_t pos = 0;
  while (true) {
    pos = s.find_first_not_of(kBlanks, pos);
    if (pos == std::string_view::npos) break;
    const auto end = std::min(s.find_first_of(kBlanks, pos), s.size());
    tokens.push_back(s.substr(pos, end - pos));
    pos = end;
  }
  return tokens;
}

// A short, printable excerpt of a value for error messages (binary junk stays one line).
std::string quote(std::string_view s) {
  constexpr std::size_t kMax = 60;
  std::string out = "'";
  for (std::size_t i = 0; i < std::min(s.size(), kMax); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > kMax) out += "...";
  return out + "'";
}

bool printable_key(std::string_view key) {
  return !key.empty() && std::all_of(key.begin(), key.end(), [](char ch) {
    const unsigned char c = static_cast<unsigned char>(ch);
    return c > 0x20 && c < 0x7f;
  });
}

// from_chars rejects a leading '+', which some writers emit.
std::string_view drop_plus(std::string_view token) {
  return (token.size() > 1 && token.front() == '+') ? token.substr(1) : token;
}

}  // namespace

void fail_file(const std::filesystem::path& path, std::string_view message) {
  throw MetaImageError(path.string() + ": " + std::string(message));
}

void MetaHeader::fail(int line, std::string_view field, std::string_view message) const {
  std::string where = path_.string();
  if (line > 0) where += ":" + std::to_string(line);
  throw MetaImageError(where + ": " + std::string(field) + ": " + std::string(message));
}

std::string read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) fail_file(path, "cannot open: no such file");
  if (std::filesystem::is_directory(status)) fail_file(path, "cannot open: is a directory");
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail_file(path, "cannot open for reading");
  const std::streamoff size = in.tellg();
  if (size < 0) fail_file(path, "cannot determine file size");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), size)) fail_file(path, "read error");
  return bytes;
}

MetaHeader MetaHeader::parse(const std::filesystem::path& path, std::string_view file_bytes) {
  MetaHeader header;
  header.path_ = path;
  std::unordered_map<std::string_view, int> first_line;  // views into file_bytes
  std::size_t pos = 0;
  int line_no = 0;
  while (pos < file_bytes.size()) {
    ++line_no;
    const std::size_t eol = file_bytes.find('\n', pos);
    const std::size_t next = eol == std::string_view::npos ? file_bytes.size() : eol + 1;
    const std::string_view line =
        file_bytes.substr(pos, (eol == std::string_view::npos ? file_bytes.size() : eol) - pos);
    pos = next;
    if (trim(line).empty()) continue;

    const std::size_t eq = line.find('=');
    const std::string_view key =
        eq == std::string_view::npos ? trim(line) : trim(line.substr(0, eq));
    if (eq == std::string_view::npos || !printable_key(key)) {
      header.fail(line_no, "header", "expected 'Key = Value', got " + quote(line));
    }
    // PLUS sequences have thousands of per-frame keys: look repeats up in a hash map.
    if (const auto [it, inserted] = first_line.try_emplace(key, line_no); !inserted) {
      header.fail(line_no, key, "repeated (first on line " + std::to_string(it->second) + ")");
    }
    header.fields_.push_back({std::string(key), std::string(trim(line.substr(eq + 1))), line_no});
    if (key == "ElementDataFile") {
      header.data_offset_ = pos;
      return header;
    }
  }
  header.fail(line_no, "ElementDataFile", "header ends without an ElementDataFile line");
}

const HeaderField* MetaHeader::find(std::string_view key) const {
  for (const auto& field : fields_) {
    if (field.key == key) return &field;
  }
  return nullptr;
}

const HeaderField* MetaHeader::find_any(std::initializer_list<std::string_view> keys) const {
  for (const auto key : keys) {
    if (const auto* field = find(key)) return field;
  }
  return nullptr;
}

const HeaderField& MetaHeader::require(std::string_view key) const {
  if (const auto* field = find(key)) return *field;
  // Name the header's last line: the field should have appeared before it.
  fail(data_file_field().line, key, "required field missing");
}

std::vector<double> MetaHeader::numbers(const HeaderField& field, std::size_t count) const {
  const auto tokens = split_blanks(field.value);
  std::vector<double> values;
  values.reserve(tokens.size());
  for (const auto raw : tokens) {
    const auto token = drop_plus(raw);
    double v = 0.0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(v)) break;
    values.push_back(v);
  }
  if (values.size() != tokens.size() || values.size() != count) {
    fail(field, "expected " + std::to_string(count) + (count == 1 ? " number" : " numbers") +
                    ", got " + quote(field.value));
  }
  return values;
}

std::vector<long long> MetaHeader::integers(const HeaderField& field, std::size_t count) const {
  const auto tokens = split_blanks(field.value);
  std::vector<long long> values;
  values.reserve(tokens.size());
  for (const auto raw : tokens) {
    const auto token = drop_plus(raw);
    long long v = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc() || end != token.data() + token.size()) break;
    values.push_back(v);
  }
  if (values.size() != tokens.size() || values.size() != count) {
    fail(field, "expected " + std::to_string(count) + (count == 1 ? " integer" : " integers") +
                    ", got " + quote(field.value));
  }
  return values;
}

bool MetaHeader::boolean(const HeaderField& field) const {
  std::string v(field.value);
  std::transform(v.begin(), v.end(), v.begin(), [](unsigned char c) { return std::tolower(c); });
  // MetaIO writes True/False; it also reads T/F and 1/0.
  if (v == "true" || v == "t" || v == "1") return true;
  if (v == "false" || v == "f" || v == "0") return false;
  fail(field, "expected True or False, got " + quote(field.value));
}

}  // namespace ultrasim::imaging::detail
