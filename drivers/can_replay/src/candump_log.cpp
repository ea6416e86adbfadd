#include "ultrasim/drivers/can_replay/candump_log.hpp"

#include <cctype>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace ultrasim::drivers::can_replay {

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

CandumpError::CandumpError(const std::string& source, int line, const std::string& what)
    : std::runtime_error(source + ":" + std::to_string(line) + ": " + what), line_(line) {}

CandumpRecord parse_candump_line(std::string_view text, const std::string& source, int line) {
  auto fail = [&](const std::string& what) -> CandumpError {
    return CandumpError(source, line, what);
  };
  CandumpRecord r;
  // "(seconds.micros)"
  if (text.empty() || text.front() != '(') throw fail("expected '(' before the timestamp");
  const std::size_t close = text.find(')');
  const std::size_t dot = text.find('.');
  if (close == std::string_view::npos || dot == std::string_view::npos || dot > close) {
    throw fail("timestamp: expected (seconds.microseconds)");
  }
  std::int64_t seconds = 0, micros = 0;
  const std::string_view sec_text = text.substr(1, dot - 1);
  const std::string_view micro_text = text.substr(dot + 1, close - dot - 1);
  if (micro_text.size() != 6 ||
      std::from_chars(sec_text.data(), sec_text.data() + sec_text.size(), seconds).ptr !=
          sec_text.data() + sec_text.size() ||
      std::from_chars(micro_text.data(), micro_text.data() + 6, micros).ptr !=
          micro_text.data() + 6) {
    throw fail("timestamp: expected (seconds.microseconds) with 6 digits of microseconds, got '" +
               std::string(text.substr(0, close + 1)) + "'");
  }
  if (seconds < 0 || seconds > std::numeric_limits<std::int64_t>::max() / 1'000'000 - 1 ||
      micro_text.front() == '-') {
    throw fail("timestamp: '" + std::string(text.substr(0, close + 1)) + "' is out of range");
  }
  r.timestamp_us = seconds * 1'000'000 + micros;
  // " interface "
  std::size_t pos = close + 1;
  while (pos < text.size() && text[pos] == ' ') ++pos;
  const std::size_t interface_end = text.find(' ', pos);
  if (interface_end == std::string_view::npos || interface_end == pos) {
    throw fail("interface: expected a name after the timestamp");
  }
  r.interface = std::string(text.substr(pos, interface_end - pos));
  pos = interface_end;
  while (pos < text.size() && text[pos] == ' ') ++pos;
  // "ID#DATA"
  const std::string_view frame = text.substr(pos);
  const std::size_t hash = frame.find('#');
  if (hash == std::string_view::npos) throw fail("frame: expected ID#DATA");
  if (hash + 1 < frame.size() && frame[hash + 1] == '#') {
    throw fail("frame: CAN FD (##) is not supported");
  }
  const std::string_view id_text = frame.substr(0, hash);
  if (id_text.size() != 3 && id_text.size() != 8) {
    throw fail("identifier: expected 3 hex digits (standard) or 8 (extended), got '" +
               std::string(id_text) + "'");
  }
  std::uint32_t id = 0;
  for (char c : id_text) {
    const int v = hex_value(c);
    if (v < 0) throw fail("identifier: '" + std::string(id_text) + "' is not hexadecimal");
    id = id << 4 | static_cast<std::uint32_t>(v);
  }
  r.frame.extended = id_text.size() == 8;
  if (r.frame.extended && (id & 0x20000000u) != 0) {
    throw fail("identifier: error frames are not supported");
  }
  r.frame.id = id & 0x1FFFFFFFu;
  if (!r.frame.extended && r.frame.id > hal::CanFrame::kMaxStandardId) {
    throw fail("identifier: " + std::string(id_text) + " does not fit 11 bits");
  }
  std::string_view data = frame.substr(hash + 1);
  while (!data.empty() && (data.back() == ' ' || data.back() == '\r')) data.remove_suffix(1);
  if (const std::size_t space = data.find(' '); space != std::string_view::npos) {
    std::string_view direction = data.substr(space + 1);
    while (!direction.empty() && direction.front() == ' ') direction.remove_prefix(1);
    if (direction != "R" && direction != "T") {
      throw fail("direction: expected R or T after the frame, got '" + std::string(direction) +
                 "'");
    }
    r.direction = direction.front();
    data = data.substr(0, space);
  }
  if (!data.empty() && (data.front() == 'R' || data.front() == 'r')) {
    r.frame.remote = true;
    if (data.size() == 2 && data[1] >= '0' && data[1] <= '8') {
      r.frame.length = static_cast<std::uint8_t>(data[1] - '0');
    } else if (data.size() != 1) {
      throw fail("data: a remote frame is R or R followed by its length 0..8");
    }
    return r;
  }
  if (data.size() % 2 != 0 || data.size() > 16) {
    throw fail("data: expected 0 to 8 bytes as pairs of hex digits, got '" + std::string(data) +
               "'");
  }
  r.frame.length = static_cast<std::uint8_t>(data.size() / 2);
  for (std::size_t i = 0; i < data.size(); i += 2) {
    const int hi = hex_value(data[i]), lo = hex_value(data[i + 1]);
    if (hi < 0 || lo < 0) throw fail("data: '" + std::string(data) + "' is not hexadecimal");
    r.frame.data[i / 2] = static_cast<std::uint8_t>(hi << 4 | lo);
  }
  return r;
}

std::string format_candump_line(const CandumpRecord& record) {
  char head[64];
  const auto seconds = record.timestamp_us / 1'000'000;
  const auto micros = record.timestamp_us % 1'000'000;
  std::snprintf(head, sizeof head, "(%lld.%06lld) ", static_cast<long long>(seconds),
                static_cast<long long>(micros));
  std::string line = head + record.interface + ' ';
  char id[16];
  std::snprintf(id, sizeof id, record.frame.extended ? "%08X#" : "%03X#",
                static_cast<unsigned>(record.frame.id));
  line += id;
  if (record.frame.remote) {
    line += 'R';
    if (record.frame.length > 0) line += static_cast<char>('0' + record.frame.length);
  } else {
    for (std::uint8_t b : record.frame.payload()) {
      char byte[3];
      std::snprintf(byte, sizeof byte, "%02X", b);
      line += byte;
    }
  }
  if (record.direction != '\0') {
    line += ' ';
    line += record.direction;
  }
  return line;
}

std::vector<CandumpRecord> parse_candump_log(std::string_view text, const std::string& source) {
  std::vector<CandumpRecord> records;
  int line_number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t newline = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, newline - pos);
    pos = newline + 1;
    ++line_number;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.remove_suffix(1);
    if (line.empty()) continue;
    records.push_back(parse_candump_line(line, source, line_number));
  }
  return records;
}

std::vector<CandumpRecord> read_candump_log(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CandumpError(path, 0, "cannot open the log");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_candump_log(text.str(), path);
}

}  // namespace ultrasim::drivers::can_replay
