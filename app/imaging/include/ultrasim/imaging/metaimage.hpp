#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "ultrasim/imaging/volume.hpp"

namespace ultrasim::imaging {

// Thrown for any unreadable, malformed or unsupported MetaImage file. what() is one line that
// names the file, the header line (when there is one) and the field, e.g.
//   "data/case/volume.mha:7: DimSize: expected 3 positive integers, got '128 0 64'"
class MetaImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads a 3D scalar MetaImage (.mha with the data inline, or .mhd + raw; raw or zlib-compressed)
// whose ElementType is MET_UCHAR. Spacing, origin (Offset/Position/Origin) and direction
// (TransformMatrix) are kept. Allocates the volume; not for the frame loop.
Volume<std::uint8_t> read_volume_u8(const std::filesystem::path& path);

// Writes a 3D MET_UCHAR MetaImage readable by ITK and 3D Slicer (.mha, data inline, zlib-compressed
// when `compress`). Byte-identical output for identical input (deterministic).
void write_volume(const std::filesystem::path& path, const Volume<std::uint8_t>& volume,
                  bool compress = true);

// A tracked freehand ultrasound sequence as PLUS writes it (.igs.mha / .seq.mha): a stack of 2D
// frames plus per-frame fields Seq_FrameNNNN_<Name> (transforms, statuses, timestamps).
struct TrackedFrame {
  double timestamp_s = 0.0;
  bool image_ok = true;                               // Seq_FrameNNNN_ImageStatus == OK
  std::map<std::string, Eigen::Matrix4d> transforms;  // "ProbeToTracker" → row-major file values
  std::map<std::string, bool> transform_ok;           // "ProbeToTracker" → status == OK
  std::map<std::string, std::string> other_fields;    // everything else, verbatim
};

struct TrackedSequence {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> pixels;  // frame-major, then row-major: frame f at f·width·height
  std::vector<TrackedFrame> frames;
  std::map<std::string, std::string> header;  // non-per-frame header fields, verbatim
};

// Reads a PLUS tracked sequence (MET_UCHAR frames, raw or zlib). Throws MetaImageError naming the
// file, line and field on anything malformed: missing frames, bad matrices, short pixel data.
TrackedSequence read_tracked_sequence(const std::filesystem::path& path);

}  // namespace ultrasim::imaging
