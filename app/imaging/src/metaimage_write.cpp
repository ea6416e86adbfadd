// write_volume: a deterministic .mha (header + inline, optionally zlib-compressed, data).

#include <array>
#include <charconv>
#include <fstream>
#include <string>
#include <system_error>

#include "metaimage_header.hpp"
#include "ultrasim/imaging/metaimage.hpp"
#include "zlib_codec.hpp"

namespace ultrasim::imaging {

namespace {

// Shortest text that reads back to the same double (std::to_chars), independent of the locale.
std::string number_text(double v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc() ? std::string(buf.data(), end) : std::string("0");
}

std::string numbers_text(std::initializer_list<double> values) {
  std::string out;
  for (const double v : values) {
    if (!out.empty()) out += ' ';
    out += number_text(v == 0.0 ? 0.0 : v);  // write -0 as 0 so equal volumes give equal bytes
  }
  return out;
}

}  // namespace

void write_volume(const std::filesystem::path& path, const Volume<std::uint8_t>& volume,
                  bool compress) {
  const auto voxels = volume.voxels();
  const std::string_view raw(reinterpret_cast<const char*>(voxels.data()), voxels.size());
  const std::string packed = compress ? detail::zlib_compress(raw) : std::string();
  const std::string_view payload = compress ? std::string_view(packed) : raw;

  const auto& d = volume.direction();
  const auto& s = volume.spacing_mm();
  const auto& o = volume.origin_mm();
  const auto& n = volume.size();
  std::string header;
  header += "ObjectType = Image\n";
  header += "NDims = 3\n";
  header += "BinaryData = True\n";
  header += "BinaryDataByteOrderMSB = False\n";
  header += compress ? "CompressedData = True\n" : "CompressedData = False\n";
  if (compress) header += "CompressedDataSize = " + std::to_string(payload.size()) + "\n";
  // Column by column (direction of index axis i first), as ITK's MetaImageIO writes it.
  header += "TransformMatrix = " +
            numbers_text(
                {d(0, 0), d(1, 0), d(2, 0), d(0, 1), d(1, 1), d(2, 1), d(0, 2), d(1, 2), d(2, 2)}) +
            "\n";
  header += "Offset = " + numbers_text({o.x(), o.y(), o.z()}) + "\n";
  header += "CenterOfRotation = 0 0 0\n";
  header += "AnatomicalOrientation = RAI\n";
  header += "ElementSpacing = " + numbers_text({s.x(), s.y(), s.z()}) + "\n";
  header += "DimSize = " + std::to_string(n.x()) + " " + std::to_string(n.y()) + " " +
            std::to_string(n.z()) + "\n";
  header += "ElementType = MET_UCHAR\n";
  header += "ElementDataFile = LOCAL\n";

  // Write beside the target and rename, so a reader never sees a half-written file.
  auto partial = path;
  partial += ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) detail::fail_file(partial, "cannot open for writing");
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.write(payload.data(), static_cast<std::streamsize>(payload.size()));
    out.close();
    if (!out) detail::fail_file(partial, "write error");
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) {
    const std::string why = ec.message();
    std::filesystem::remove(partial, ec);
    detail::fail_file(path, "cannot replace file: " + why);
  }
}

}  // namespace ultrasim::imaging
