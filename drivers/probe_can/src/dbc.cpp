#include "ultrasim/drivers/probe_can/dbc.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

namespace ultrasim::drivers::probe_can {

namespace {

constexpr std::uint32_t kExtendedIdFlag = 0x80000000u;

// Reads one DBC line left to right; every failure names the field it expected.
class LineScanner {
 public:
  LineScanner(std::string_view line, const std::string& source, int line_number)
      : line_(line), source_(source), line_number_(line_number) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw DbcError(source_, line_number_, what);
  }
  void skip_space() {
    while (pos_ < line_.size() && (line_[pos_] == ' ' || line_[pos_] == '\t')) ++pos_;
  }
  bool at_end() {
    skip_space();
    return pos_ >= line_.size();
  }
  bool peek(char c) {
    skip_space();
    return pos_ < line_.size() && line_[pos_] == c;
  }
  void expect(char c, const char* field) {
    if (!peek(c)) fail(std::string("expected '") + c + "' " + field);
    ++pos_;
  }
  std::string identifier(const char* field) {
    skip_space();
    const std::size_t start = pos_;
    while (pos_ < line_.size() &&
           (std::isalnum(static_cast<unsigned char>(line_[pos_])) != 0 || line_[pos_] == '_')) {
      ++pos_;
    }
    if (pos_ == start) fail(std::string("expected a name for ") + field);
    return std::string(line_.substr(start, pos_ - start));
  }
  template <typename T>
  T number(const char* field) {
    skip_space();
    T value{};
    const char* begin = line_.data() + pos_;
    const char* end = line_.data() + line_.size();
    // from_chars takes no leading '+'.
    if (begin != end && *begin == '+') ++begin;
    const auto [ptr, ec] = std::from_chars(begin, end, value);
    if (ec != std::errc{}) {
      fail(std::string("expected a number for ") + field + " at '" +
           std::string(line_.substr(pos_, 12)) + "'");
    }
    pos_ = static_cast<std::size_t>(ptr - line_.data());
    return value;
  }
  std::string quoted(const char* field) {
    expect('"', field);
    const std::size_t close = line_.find('"', pos_);
    if (close == std::string_view::npos) fail(std::string("unterminated string for ") + field);
    std::string text(line_.substr(pos_, close - pos_));
    pos_ = close + 1;
    return text;
  }
  char next_char(const char* field) {
    skip_space();
    if (pos_ >= line_.size()) fail(std::string("line ends before ") + field);
    return line_[pos_++];
  }

 private:
  std::string_view line_;
  const std::string& source_;
  int line_number_;
  std::size_t pos_ = 0;
};

std::string_view trimmed(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

bool starts_with_word(std::string_view line, std::string_view word) {
  return line.size() >= word.size() && line.substr(0, word.size()) == word &&
         (line.size() == word.size() || line[word.size()] == ' ' || line[word.size()] == '\t' ||
          line[word.size()] == ':');
}

DbcMessage parse_message(LineScanner& in) {
  DbcMessage m;
  const auto raw_id = in.number<std::uint32_t>("the message identifier");
  m.extended = (raw_id & kExtendedIdFlag) != 0;
  m.id = raw_id & ~kExtendedIdFlag;
  if (m.id > (m.extended ? 0x1FFFFFFFu : 0x7FFu)) {
    in.fail("message identifier " + std::to_string(m.id) + " does not fit " +
            (m.extended ? "29" : "11") + " bits");
  }
  m.name = in.identifier("the message");
  in.expect(':', "after the message name");
  m.length_bytes = in.number<int>("the message length");
  if (m.length_bytes < 0 || m.length_bytes > 8) {
    in.fail("message length " + std::to_string(m.length_bytes) + " is not 0..8 (classic CAN)");
  }
  m.sender = in.identifier("the sender");
  return m;
}

DbcSignal parse_signal(LineScanner& in, const DbcMessage& message) {
  DbcSignal s;
  s.name = in.identifier("the signal");
  if (!in.peek(':')) {
    in.fail("signal " + s.name + " is multiplexed: not supported");
  }
  in.expect(':', "after the signal name");
  s.start_bit = in.number<int>("the start bit");
  in.expect('|', "between start bit and length");
  s.length_bits = in.number<int>("the length");
  in.expect('@', "before the byte order");
  const char order = in.next_char("the byte order");
  if (order == '0') in.fail("signal " + s.name + " is big-endian (Motorola): not supported");
  if (order != '1') in.fail(std::string("byte order must be 0 or 1, not '") + order + "'");
  const char sign = in.next_char("the sign");
  if (sign != '+' && sign != '-') in.fail(std::string("sign must be + or -, not '") + sign + "'");
  s.is_signed = sign == '-';
  in.expect('(', "before the factor");
  s.factor = in.number<double>("the factor");
  in.expect(',', "between factor and offset");
  s.offset = in.number<double>("the offset");
  in.expect(')', "after the offset");
  in.expect('[', "before the minimum");
  s.minimum = in.number<double>("the minimum");
  in.expect('|', "between minimum and maximum");
  s.maximum = in.number<double>("the maximum");
  in.expect(']', "after the maximum");
  s.unit = in.quoted("the unit");
  // Raw values live in an int64_t and go through a double: 62 bits keep both exact enough.
  if (s.length_bits < 1 || s.length_bits > 62) {
    in.fail("signal " + s.name + ": length " + std::to_string(s.length_bits) + " is not 1..62");
  }
  if (s.start_bit < 0 || s.start_bit > 8 * message.length_bytes - s.length_bits) {
    const long long last = static_cast<long long>(s.start_bit) + s.length_bits - 1;
    in.fail("signal " + s.name + " (bits " + std::to_string(s.start_bit) + ".." +
            std::to_string(last) + ") lies outside message " + message.name + "'s " +
            std::to_string(message.length_bytes) + " bytes");
  }
  if (!(s.minimum <= s.maximum)) {
    in.fail("signal " + s.name + ": minimum above maximum");
  }
  if (!(s.factor != 0.0) || !std::isfinite(s.factor) || !std::isfinite(s.offset)) {
    in.fail("signal " + s.name + ": factor must be finite and non-zero, offset finite");
  }
  for (const DbcSignal& other : message.signals) {
    if (other.name == s.name) in.fail("signal " + s.name + " appears twice in " + message.name);
    const bool apart = s.start_bit + s.length_bits <= other.start_bit ||
                       other.start_bit + other.length_bits <= s.start_bit;
    if (!apart) in.fail("signal " + s.name + " overlaps " + other.name);
  }
  return s;
}

void parse_value_names(LineScanner& in, DbcDatabase& db) {
  const auto raw_id = in.number<std::uint32_t>("the message identifier");
  const std::uint32_t id = raw_id & ~kExtendedIdFlag;
  const std::string signal_name = in.identifier("the signal");
  DbcMessage* message = nullptr;
  for (auto& m : db.messages) {
    if (m.id == id) message = &m;
  }
  if (message == nullptr) in.fail("VAL_ for unknown message " + std::to_string(id));
  DbcSignal* signal = nullptr;
  for (auto& s : message->signals) {
    if (s.name == signal_name) signal = &s;
  }
  if (signal == nullptr) {
    in.fail("VAL_ for unknown signal " + signal_name + " of " + message->name);
  }
  while (!in.peek(';')) {
    const auto raw = in.number<std::int64_t>("a raw value");
    signal->value_names[raw] = in.quoted("the value's name");
  }
}

std::uint64_t low_bits_mask(int bits) {
  return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
}

}  // namespace

DbcError::DbcError(const std::string& source, int line, const std::string& what)
    : std::runtime_error(source + ":" + std::to_string(line) + ": " + what), line_(line) {}

const DbcSignal* DbcMessage::signal(std::string_view wanted) const {
  for (const auto& s : signals) {
    if (s.name == wanted) return &s;
  }
  return nullptr;
}

const DbcMessage* DbcDatabase::message(std::uint32_t id) const {
  for (const auto& m : messages) {
    if (m.id == id) return &m;
  }
  return nullptr;
}

const DbcMessage* DbcDatabase::message(std::string_view name) const {
  for (const auto& m : messages) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

DbcDatabase parse_dbc(std::string_view text, const std::string& source) {
  DbcDatabase db;
  int line_number = 0;
  bool in_comment = false;        // inside a CM_ statement, which may span lines
  bool in_new_symbols = false;    // inside NS_'s indented list of keywords (CM_, VAL_, ...)
  bool skipping_message = false;  // inside VECTOR__INDEPENDENT_SIG_MSG, a holder of no frame
  DbcMessage* current = nullptr;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t newline = std::min(text.find('\n', pos), text.size());
    const std::string_view raw_line = text.substr(pos, newline - pos);
    const std::string_view line = trimmed(raw_line);
    pos = newline + 1;
    ++line_number;
    if (in_new_symbols) {
      if (!raw_line.empty() && (raw_line.front() == ' ' || raw_line.front() == '\t')) continue;
      in_new_symbols = false;
    }
    if (starts_with_word(line, "NS_")) {
      in_new_symbols = true;
      continue;
    }
    if (skipping_message) {
      if (starts_with_word(line, "SG_")) continue;
      skipping_message = false;
    }
    if (in_comment || starts_with_word(line, "CM_")) {
      // A comment's text is quoted and the statement ends with ';' after the closing quote.
      const bool ends = line.size() >= 2 && line.substr(line.size() - 2) == "\";";
      in_comment = !ends;
      continue;
    }
    LineScanner in(line, source, line_number);
    if (starts_with_word(line, "VERSION")) {
      LineScanner version(line.substr(7), source, line_number);
      db.version = version.quoted("the version");
    } else if (starts_with_word(line, "BO_")) {
      LineScanner body(line.substr(3), source, line_number);
      if (line.find("VECTOR__INDEPENDENT_SIG_MSG") != std::string_view::npos) {
        skipping_message = true;  // Vector's placeholder for signals sent in no message
        current = nullptr;
        continue;
      }
      DbcMessage m = parse_message(body);
      if (db.message(m.id) != nullptr) {
        body.fail("message identifier " + std::to_string(m.id) + " is defined twice");
      }
      db.messages.push_back(std::move(m));
      current = &db.messages.back();
    } else if (starts_with_word(line, "SG_")) {
      LineScanner body(line.substr(3), source, line_number);
      if (current == nullptr) body.fail("SG_ before any BO_");
      DbcSignal s = parse_signal(body, *current);
      current->signals.push_back(std::move(s));
    } else if (starts_with_word(line, "VAL_")) {
      LineScanner body(line.substr(4), source, line_number);
      parse_value_names(body, db);
    } else if (line.empty()) {
      current = nullptr;  // a message's signals end at the first blank line
    }
  }
  if (in_comment) throw DbcError(source, line_number, "a CM_ comment is not closed");
  return db;
}

std::int64_t read_raw(const DbcSignal& signal, std::span<const std::uint8_t> data) {
  std::uint64_t raw = 0;
  for (int i = 0; i < signal.length_bits; ++i) {
    const int bit = signal.start_bit + i;
    const std::uint64_t b = (data[static_cast<std::size_t>(bit / 8)] >> (bit % 8)) & 1u;
    raw |= b << i;
  }
  if (signal.is_signed && signal.length_bits < 64 && (raw >> (signal.length_bits - 1) & 1u) != 0) {
    raw |= ~low_bits_mask(signal.length_bits);  // sign-extend
  }
  return static_cast<std::int64_t>(raw);
}

void write_raw(const DbcSignal& signal, std::int64_t raw, std::span<std::uint8_t> data) {
  const auto bits = static_cast<std::uint64_t>(raw) & low_bits_mask(signal.length_bits);
  for (int i = 0; i < signal.length_bits; ++i) {
    const int bit = signal.start_bit + i;
    auto& byte = data[static_cast<std::size_t>(bit / 8)];
    const auto mask = static_cast<std::uint8_t>(1u << (bit % 8));
    byte = static_cast<std::uint8_t>(((bits >> i) & 1u) != 0 ? (byte | mask) : (byte & ~mask));
  }
}

double to_physical(const DbcSignal& signal, std::int64_t raw) {
  return static_cast<double>(raw) * signal.factor + signal.offset;
}

std::optional<std::int64_t> to_raw(const DbcSignal& signal, double physical) {
  if (!std::isfinite(physical)) return std::nullopt;
  const double raw = std::round((physical - signal.offset) / signal.factor);
  const int bits = signal.length_bits;
  // Exclusive upper bound: 2^bits − 1 is not exact in a double from 54 bits on.
  const double lowest = signal.is_signed ? -std::ldexp(1.0, bits - 1) : 0.0;
  const double beyond = std::ldexp(1.0, signal.is_signed ? bits - 1 : bits);
  if (!(raw >= lowest && raw < beyond)) return std::nullopt;
  return static_cast<std::int64_t>(raw);
}

}  // namespace ultrasim::drivers::probe_can
