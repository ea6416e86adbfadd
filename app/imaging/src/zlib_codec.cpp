#include "zlib_codec.hpp"

#include <zlib.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace ultrasim::imaging::detail {

namespace {

// zlib's avail_in/avail_out are 32-bit; feed large buffers in chunks of at most this.
constexpr std::size_t kMaxChunk = std::numeric_limits<uInt>::max();

}  // namespace

std::string zlib_compress(std::string_view data) {
  z_stream zs{};
  if (deflateInit(&zs, kZlibLevel) != Z_OK) throw std::runtime_error("zlib: deflateInit failed");
  std::string out(deflateBound(&zs, static_cast<uLong>(data.size())), '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  std::size_t in_left = data.size();
  std::size_t out_left = out.size();
  int rc = Z_OK;
  while (rc == Z_OK) {
    const auto in_chunk = static_cast<uInt>(std::min(in_left, kMaxChunk));
    const auto out_chunk = static_cast<uInt>(std::min(out_left, kMaxChunk));
    zs.avail_in = in_chunk;
    zs.avail_out = out_chunk;
    rc = deflate(&zs, in_left == in_chunk ? Z_FINISH : Z_NO_FLUSH);
    in_left -= in_chunk - zs.avail_in;
    out_left -= out_chunk - zs.avail_out;
  }
  const std::size_t written = out.size() - out_left;
  deflateEnd(&zs);
  if (rc != Z_STREAM_END) throw std::runtime_error("zlib: deflate failed");
  out.resize(written);
  return out;
}

InflateStatus zlib_inflate_exact(std::string_view compressed, std::span<std::uint8_t> out,
                                 std::size_t& produced) {
  produced = 0;
  z_stream zs{};
  // 15 + 32: accept a zlib or a gzip wrapper (MetaIO writes zlib; gzip costs nothing to allow).
  if (inflateInit2(&zs, 15 + 32) != Z_OK) return InflateStatus::kCorrupt;
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(compressed.data()));
  zs.next_out = out.data();
  std::size_t in_left = compressed.size();
  std::size_t out_left = out.size();
  InflateStatus status = InflateStatus::kOk;
  for (;;) {
    const auto in_chunk = static_cast<uInt>(std::min(in_left, kMaxChunk));
    const auto out_chunk = static_cast<uInt>(std::min(out_left, kMaxChunk));
    zs.avail_in = in_chunk;
    zs.avail_out = out_chunk;
    const int rc = inflate(&zs, Z_NO_FLUSH);
    in_left -= in_chunk - zs.avail_in;
    out_left -= out_chunk - zs.avail_out;
    if (rc == Z_STREAM_END) {
      status = out_left == 0 ? InflateStatus::kOk : InflateStatus::kTooShort;
      break;
    }
    if (rc == Z_NEED_DICT || rc == Z_DATA_ERROR || rc == Z_MEM_ERROR || rc == Z_STREAM_ERROR) {
      status = InflateStatus::kCorrupt;
      break;
    }
    if (out_left == 0 && zs.avail_out == 0) {
      // Output full but the stream goes on: probe with one spare byte whether more data follows
      // or only the stream trailer (adler32) was left to read.
      unsigned char spare = 0;
      zs.next_out = &spare;
      zs.avail_out = 1;
      zs.avail_in = static_cast<uInt>(std::min(in_left, kMaxChunk));
      const uInt before = zs.avail_in;
      const int rc2 = inflate(&zs, Z_NO_FLUSH);
      in_left -= before - zs.avail_in;
      if (rc2 == Z_STREAM_END && zs.avail_out == 1) {
        status = InflateStatus::kOk;
      } else if (zs.avail_out == 0) {
        status = InflateStatus::kTooLong;
      } else if (rc2 == Z_DATA_ERROR) {
        status = InflateStatus::kCorrupt;
      } else {
        status = InflateStatus::kTruncated;
      }
      break;
    }
    if (in_left == 0 && (rc == Z_BUF_ERROR || zs.avail_in == 0)) {
      status = InflateStatus::kTruncated;
      break;
    }
  }
  produced = out.size() - out_left;
  inflateEnd(&zs);
  return status;
}

}  // namespace ultrasim::imaging::detail
