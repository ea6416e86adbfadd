#pragma once

// Private to app/imaging: the zlib streams MetaImage uses for CompressedData = True.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace ultrasim::imaging::detail {

// zlib level used by the writer. Fixed (not Z_DEFAULT_COMPRESSION, whose meaning a zlib build may
// change) so that identical volumes give identical files.
inline constexpr int kZlibLevel = 6;

// Compresses `data` into one zlib stream at kZlibLevel. Allocates the result. Throws
// std::runtime_error only if zlib itself fails (out of memory).
std::string zlib_compress(std::string_view data);

// Why an inflate failed; the caller turns it into a MetaImageError naming the file and field.
enum class InflateStatus { kOk, kCorrupt, kTruncated, kTooLong, kTooShort };

// Inflates one zlib (or gzip) stream from `compressed` into exactly `out.size()` bytes.
// kTooLong: the stream holds more than out.size() bytes; kTooShort: it ends before filling out;
// kTruncated: the input ends before the stream does; kCorrupt: zlib reports bad data.
// `produced` receives the number of bytes written. Does not allocate beyond zlib's own state.
InflateStatus zlib_inflate_exact(std::string_view compressed, std::span<std::uint8_t> out,
                                 std::size_t& produced);

}  // namespace ultrasim::imaging::detail
