#include "metaimage_layout.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string>

#include "zlib_codec.hpp"

namespace ultrasim::imaging::detail {

namespace {

// Largest image we accept: 4 GiB of voxels. Guards the allocation against a corrupt DimSize.
constexpr std::size_t kMaxImageBytes = std::size_t{1} << 32;

// deflate cannot compress better than about 1032:1; a DimSize that would need more is corrupt
// and is rejected before allocating.
constexpr std::size_t kMaxDeflateRatio = 1032;

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

std::string dims_text(const ImageLayout& layout) {
  return std::to_string(layout.size.x()) + " " + std::to_string(layout.size.y()) + " " +
         std::to_string(layout.size.z());
}

}  // namespace

ImageLayout parse_uchar_layout(const MetaHeader& header) {
  ImageLayout layout;

  if (const auto* type = header.find("ObjectType"); type && !iequals(type->value, "Image")) {
    header.fail(*type, "expected Image, got '" + type->value + "'");
  }

  const auto& ndims = header.require("NDims");
  if (header.integers(ndims, 1)[0] != 3) {
    header.fail(ndims, "expected 3 (only 3D images are supported), got '" + ndims.value + "'");
  }

  const auto& dims = header.require("DimSize");
  const auto dim_values = header.integers(dims, 3);
  std::size_t bytes = 1;
  for (int a = 0; a < 3; ++a) {
    const long long d = dim_values[static_cast<std::size_t>(a)];
    if (d <= 0 || d > std::numeric_limits<int>::max()) {
      header.fail(dims, "expected 3 positive integers, got '" + dims.value + "'");
    }
    layout.size[a] = static_cast<int>(d);
    if (static_cast<std::size_t>(d) > kMaxImageBytes / bytes) {
      header.fail(dims, "image larger than 4 GiB: '" + dims.value + "'");
    }
    bytes *= static_cast<std::size_t>(d);
  }
  layout.byte_count = bytes;

  const auto& type = header.require("ElementType");
  if (type.value != "MET_UCHAR") {
    header.fail(type,
                "unsupported element type '" + type.value + "' (only MET_UCHAR is supported)");
  }
  if (const auto* channels = header.find("ElementNumberOfChannels")) {
    if (header.integers(*channels, 1)[0] != 1) {
      header.fail(*channels, "expected 1 (scalar images only), got '" + channels->value + "'");
    }
  }
  if (const auto* binary = header.find("BinaryData"); binary && !header.boolean(*binary)) {
    header.fail(*binary, "ASCII element data is not supported");
  }
  // Byte order does not matter for one-byte elements, but a malformed value is still an error.
  if (const auto* msb = header.find_any({"BinaryDataByteOrderMSB", "ElementByteOrderMSB"})) {
    (void)header.boolean(*msb);
  }
  if (const auto* compressed = header.find("CompressedData")) {
    layout.compressed = header.boolean(*compressed);
  }

  // MetaIO: ElementSpacing is the grid step; ElementSize (the voxel's physical extent) stands in
  // for it when absent; with neither, spacing is 1.
  if (const auto* spacing = header.find_any({"ElementSpacing", "ElementSize"})) {
    const auto values = header.numbers(*spacing, 3);
    for (int a = 0; a < 3; ++a) {
      layout.spacing_mm[a] = values[static_cast<std::size_t>(a)];
      if (!(layout.spacing_mm[a] > 0.0)) {
        header.fail(*spacing, "expected 3 positive numbers, got '" + spacing->value + "'");
      }
    }
  }
  if (const auto* origin = header.find_any({"Offset", "Position", "Origin"})) {
    const auto values = header.numbers(*origin, 3);
    layout.origin_mm = Eigen::Vector3d(values[0], values[1], values[2]);
  }
  // ITK (MetaImageIO) writes TransformMatrix[i·3 + j] = direction(j, i): the numbers list the
  // direction matrix column by column, i.e. the world direction of index axis i is numbers
  // 3i..3i+2. Reading uses the same rule, so identity and ITK files round-trip unchanged.
  if (const auto* matrix = header.find_any({"TransformMatrix", "Rotation", "Orientation"})) {
    const auto values = header.numbers(*matrix, 9);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        layout.direction(j, i) = values[static_cast<std::size_t>(i * 3 + j)];
    }
    if (!(std::abs(layout.direction.determinant()) > 1e-6)) {
      header.fail(*matrix, "singular direction matrix '" + matrix->value + "'");
    }
  }
  return layout;
}

std::vector<std::uint8_t> read_element_bytes(const MetaHeader& header, std::string_view file_bytes,
                                             const ImageLayout& layout) {
  const HeaderField& data_field = header.data_file_field();
  std::string external_bytes;  // holds a separate data file's content while we read it
  std::string_view payload;
  if (iequals(data_field.value, "LOCAL")) {
    payload = file_bytes.substr(header.data_offset());
  } else {
    if (iequals(data_field.value, "LIST") || data_field.value.find('%') != std::string::npos ||
        data_field.value.empty()) {
      header.fail(data_field, "only LOCAL or a single data file name is supported, got '" +
                                  data_field.value + "'");
    }
    const auto data_path = header.path().parent_path() / data_field.value;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(data_path, ec)) {
      header.fail(data_field, "data file '" + data_path.string() + "' not found");
    }
    external_bytes = read_file_bytes(data_path);
    payload = external_bytes;
    if (const auto* skip = header.find("HeaderSize")) {
      const long long n = header.integers(*skip, 1)[0];
      if (n == -1) {
        // MetaIO: -1 means "the data is the last bytes of the file".
        if (layout.compressed) header.fail(*skip, "-1 is not supported with compressed data");
        if (payload.size() >= layout.byte_count) {
          payload = payload.substr(payload.size() - layout.byte_count);
        }
      } else if (n < 0 || static_cast<std::size_t>(n) > payload.size()) {
        header.fail(*skip, "expected -1 or 0.." + std::to_string(payload.size()) + ", got '" +
                               skip->value + "'");
      } else {
        payload = payload.substr(static_cast<std::size_t>(n));
      }
    }
  }

  if (!layout.compressed) {
    if (payload.size() != layout.byte_count) {
      header.fail(data_field,
                  std::string(payload.size() < layout.byte_count ? "truncated" : "too long") +
                      ": " + std::to_string(payload.size()) + " bytes of element data, DimSize " +
                      dims_text(layout) + " needs " + std::to_string(layout.byte_count));
    }
    return {payload.begin(), payload.end()};
  }

  if (const auto* csize_field = header.find("CompressedDataSize")) {
    const long long csize = header.integers(*csize_field, 1)[0];
    if (csize < 0)
      header.fail(*csize_field, "expected a byte count, got '" + csize_field->value + "'");
    if (static_cast<std::size_t>(csize) > payload.size()) {
      header.fail(*csize_field, "truncated: header says " + std::to_string(csize) +
                                    " compressed bytes, file holds " +
                                    std::to_string(payload.size()));
    }
    payload = payload.substr(0, static_cast<std::size_t>(csize));
  }
  if (layout.byte_count / kMaxDeflateRatio > payload.size() + 1) {
    header.fail(data_field, "DimSize " + dims_text(layout) + " needs " +
                                std::to_string(layout.byte_count) + " bytes, more than " +
                                std::to_string(payload.size()) + " zlib bytes can hold");
  }

  std::vector<std::uint8_t> out(layout.byte_count);
  std::size_t produced = 0;
  const auto need =
      " bytes, DimSize " + dims_text(layout) + " needs " + std::to_string(layout.byte_count);
  switch (zlib_inflate_exact(payload, out, produced)) {
    case InflateStatus::kOk:
      return out;
    case InflateStatus::kCorrupt:
      header.fail(data_field, "corrupt zlib data after " + std::to_string(produced) + " bytes");
    case InflateStatus::kTruncated:
      header.fail(data_field, "truncated zlib data: inflated " + std::to_string(produced) + need);
    case InflateStatus::kTooShort:
      header.fail(data_field, "zlib data inflates to " + std::to_string(produced) + need);
    case InflateStatus::kTooLong:
      header.fail(data_field, "zlib data inflates to more than " + std::to_string(produced) + need);
  }
  header.fail(data_field, "unknown zlib status");
}

}  // namespace ultrasim::imaging::detail
