#pragma once

// Private to app/imaging: the image grid a MetaImage header describes, and its element bytes.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "metaimage_header.hpp"

namespace ultrasim::imaging::detail {

// The grid of a 3D MET_UCHAR, single-channel, binary MetaImage, as checked from its header.
struct ImageLayout {
  Eigen::Vector3i size = Eigen::Vector3i::Zero();  // DimSize
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  bool compressed = false;
  std::size_t byte_count = 0;  // size.prod() for MET_UCHAR
};

// Checks NDims 3, DimSize, ElementType MET_UCHAR, ElementNumberOfChannels 1, BinaryData, and
// reads spacing (ElementSpacing, else ElementSize, else 1 as MetaIO does), origin
// (Offset/Position/Origin, else 0) and direction (TransformMatrix/Rotation/Orientation, else
// identity). Throws MetaImageError naming the offending field.
ImageLayout parse_uchar_layout(const MetaHeader& header);

// Returns the `layout.byte_count` element bytes: inline (ElementDataFile = LOCAL) or from the
// data file named by ElementDataFile (relative to the header's folder), raw or zlib as
// CompressedData says. `file_bytes` is the whole header file. Throws MetaImageError on truncated
// data, a wrong decompressed size or a corrupt zlib stream. Allocates the result.
std::vector<std::uint8_t> read_element_bytes(const MetaHeader& header, std::string_view file_bytes,
                                             const ImageLayout& layout);

}  // namespace ultrasim::imaging::detail
