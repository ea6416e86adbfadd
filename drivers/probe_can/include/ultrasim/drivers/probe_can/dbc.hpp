#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace ultrasim::drivers::probe_can {

// A DBC file's contents that a codec needs (Vector's CAN database format): messages, their
// signals and value names. Only little-endian (Intel, "@1") signals are supported; the parser
// refuses Motorola ones rather than decode them wrongly.

struct DbcSignal {
  std::string name;
  int start_bit = 0;  // of the least significant bit, counting bit 0 of byte 0 up
  int length_bits = 1;
  bool is_signed = false;  // two's complement
  double factor = 1.0;     // physical = raw × factor + offset
  double offset = 0.0;
  double minimum = 0.0;  // the physical range the file declares
  double maximum = 0.0;
  std::string unit;
  std::map<std::int64_t, std::string> value_names;  // VAL_ entries, raw value → name
};

struct DbcMessage {
  std::uint32_t id = 0;
  bool extended = false;  // the file sets bit 31 of the identifier for a 29-bit one
  std::string name;
  int length_bytes = 8;
  std::string sender;
  std::vector<DbcSignal> signals;

  // nullptr when it has no such signal.
  const DbcSignal* signal(std::string_view name) const;
};

struct DbcDatabase {
  std::string version;
  std::vector<DbcMessage> messages;

  const DbcMessage* message(std::uint32_t id) const;       // nullptr when unknown
  const DbcMessage* message(std::string_view name) const;  // nullptr when unknown
};

// A file that does not parse: names the source, the line (1-based) and what was wrong there.
class DbcError : public std::runtime_error {
 public:
  DbcError(const std::string& source, int line, const std::string& what);
  int line() const { return line_; }

 private:
  int line_;
};

// Parses `text` (named `source` in errors). Reads VERSION, BO_, SG_ and VAL_; skips the other
// sections (NS_'s list of keywords included) and Vector's VECTOR__INDEPENDENT_SIG_MSG. Throws
// DbcError for a malformed BO_/SG_/VAL_ line, a signal outside its message's bytes or longer than
// 62 bits, a minimum above its maximum, overlapping signals, a duplicate message identifier or
// signal name, a Motorola signal, or a multiplexed one. Allocates.
DbcDatabase parse_dbc(std::string_view text, const std::string& source);

// The raw (integer) value of a signal in `data` (the message's bytes), sign-extended when signed.
std::int64_t read_raw(const DbcSignal& signal, std::span<const std::uint8_t> data);
// Writes the raw value's low length_bits bits into `data`, leaving the other bits as they are.
void write_raw(const DbcSignal& signal, std::int64_t raw, std::span<std::uint8_t> data);

// Physical value ↔ raw: raw × factor + offset; to raw rounds to nearest. std::nullopt when the
// physical value is not finite or its raw value does not fit the signal's bits.
double to_physical(const DbcSignal& signal, std::int64_t raw);
std::optional<std::int64_t> to_raw(const DbcSignal& signal, double physical);

}  // namespace ultrasim::drivers::probe_can
