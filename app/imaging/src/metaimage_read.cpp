// read_volume_u8: a 3D MET_UCHAR MetaImage into a Volume.

#include <algorithm>

#include "metaimage_header.hpp"
#include "metaimage_layout.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {

Volume<std::uint8_t> read_volume_u8(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  const auto header = detail::MetaHeader::parse(path, bytes);
  const auto layout = detail::parse_uchar_layout(header);
  const auto elements = detail::read_element_bytes(header, bytes, layout);

  Volume<std::uint8_t> volume(layout.size, layout.spacing_mm, layout.origin_mm, layout.direction);
  std::copy(elements.begin(), elements.end(), volume.voxels().begin());
  return volume;
}

}  // namespace ultrasim::imaging
