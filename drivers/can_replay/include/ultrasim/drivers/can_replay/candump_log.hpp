#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/hal/can_bus.hpp"

namespace ultrasim::drivers::can_replay {

// One line of a `candump -l` log (can-utils' log format, also python-can's CanutilsLogWriter):
//   (1700000000.123456) can0 101#0011223344556677
// a timestamp in seconds with microseconds, the interface, and the frame: 3 hex digits of
// identifier for a standard frame, 8 for an extended one, '#', then the data bytes in hex
// ("R" and an optional length digit for a remote frame), and, in newer logs (python-can,
// can-utils with -x), " R" or " T" for a received or transmitted frame. CAN FD ("##") and error
// frames are not part of our protocol and are refused.
struct CandumpRecord {
  std::int64_t timestamp_us = 0;  // as logged: µs since the epoch of the logging machine
  std::string interface;
  hal::CanFrame frame;
  char direction = '\0';  // 'R' received, 'T' transmitted, '\0' not logged
};

// A log line that does not parse: names the source, the line and the field.
class CandumpError : public std::runtime_error {
 public:
  CandumpError(const std::string& source, int line, const std::string& what);
  int line() const { return line_; }

 private:
  int line_;
};

// Parses one line (no trailing newline). Throws CandumpError naming `source` and `line`.
CandumpRecord parse_candump_line(std::string_view text, const std::string& source, int line);

// The line for a record, as candump -l writes it (upper-case hex).
std::string format_candump_line(const CandumpRecord& record);

// Every record of a log's text (blank lines skipped); throws at the first bad line. Allocates.
std::vector<CandumpRecord> parse_candump_log(std::string_view text, const std::string& source);

// Reads a log file; throws CandumpError (line 0 when the file cannot be read).
std::vector<CandumpRecord> read_candump_log(const std::string& path);

}  // namespace ultrasim::drivers::can_replay
