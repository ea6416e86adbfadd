// read_tracked_sequence: a PLUS .igs.mha / .seq.mha (2D frames stacked along DimSize[2], with
// per-frame Seq_FrameNNNN_<Name> header fields).

#include <cctype>
#include <string>
#include <string_view>

#include "metaimage_header.hpp"
#include "metaimage_layout.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::imaging {

namespace {

constexpr std::string_view kFramePrefix = "Seq_Frame";
constexpr std::string_view kTransformSuffix = "Transform";
constexpr std::string_view kStatusSuffix = "TransformStatus";

struct FrameKey {
  std::size_t frame = 0;
  std::string_view name;  // the part after "Seq_FrameNNNN_"
};

// Splits "Seq_Frame0012_ProbeToTrackerTransform" into (12, "ProbeToTrackerTransform").
// PLUS pads the number to four digits but writes more for longer sequences.
bool parse_frame_key(std::string_view key, FrameKey& out) {
  if (!key.starts_with(kFramePrefix)) return false;
  std::size_t pos = kFramePrefix.size();
  std::size_t frame = 0;
  const std::size_t digits_begin = pos;
  while (pos < key.size() && std::isdigit(static_cast<unsigned char>(key[pos]))) {
    if (pos - digits_begin >= 9) return false;  // no sequence has a billion frames
    frame = frame * 10 + static_cast<std::size_t>(key[pos] - '0');
    ++pos;
  }
  if (pos == digits_begin || pos + 1 >= key.size() || key[pos] != '_') return false;
  out.frame = frame;
  out.name = key.substr(pos + 1);
  return true;
}

std::string frame_field(std::size_t frame, std::string_view name) {
  std::string number = std::to_string(frame);
  if (number.size() < 4) number.insert(0, 4 - number.size(), '0');
  return std::string(kFramePrefix) + number + "_" + std::string(name);
}

// PLUS writes OK or INVALID; anything but OK (any case) counts as not usable.
bool status_ok(std::string_view value) {
  return value.size() == 2 && std::toupper(static_cast<unsigned char>(value[0])) == 'O' &&
         std::toupper(static_cast<unsigned char>(value[1])) == 'K';
}

}  // namespace

TrackedSequence read_tracked_sequence(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  const auto header = detail::MetaHeader::parse(path, bytes);
  const auto layout = detail::parse_uchar_layout(header);

  TrackedSequence seq;
  seq.width_px = layout.size.x();
  seq.height_px = layout.size.y();
  const auto frame_count = static_cast<std::size_t>(layout.size.z());
  seq.frames.resize(frame_count);
  std::vector<bool> has_timestamp(frame_count, false);

  for (const auto& field : header.fields()) {
    FrameKey key;
    if (!parse_frame_key(field.key, key)) {
      seq.header.emplace(field.key, field.value);
      continue;
    }
    if (key.frame >= frame_count) {
      header.fail(field, "frame " + std::to_string(key.frame) + " beyond the " +
                             std::to_string(frame_count) + " frames of DimSize");
    }
    TrackedFrame& frame = seq.frames[key.frame];
    const std::string_view name = key.name;
    if (name == "Timestamp") {
      frame.timestamp_s = header.numbers(field, 1)[0];
      has_timestamp[key.frame] = true;
    } else if (name == "ImageStatus") {
      frame.image_ok = status_ok(field.value);
    } else if (name.size() > kStatusSuffix.size() && name.ends_with(kStatusSuffix)) {
      const auto transform = name.substr(0, name.size() - kStatusSuffix.size());
      frame.transform_ok[std::string(transform)] = status_ok(field.value);
    } else if (name.size() > kTransformSuffix.size() && name.ends_with(kTransformSuffix)) {
      const auto values = header.numbers(field, 16);
      Eigen::Matrix4d m;
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) m(r, c) = values[static_cast<std::size_t>(r * 4 + c)];
      }
      const std::string transform(name.substr(0, name.size() - kTransformSuffix.size()));
      frame.transforms[transform] = m;
      // A matrix without a status line is taken as valid (the status is what marks it bad);
      // try_emplace keeps a status that appeared earlier in the header.
      frame.transform_ok.try_emplace(transform, true);
    } else {
      frame.other_fields.emplace(std::string(name), field.value);
    }
  }
  for (std::size_t f = 0; f < frame_count; ++f) {
    if (!has_timestamp[f]) {
      header.fail(
          header.data_file_field().line, frame_field(f, "Timestamp"),
          "required field missing (DimSize declares " + std::to_string(frame_count) + " frames)");
    }
  }

  seq.pixels = detail::read_element_bytes(header, bytes, layout);
  return seq;
}

}  // namespace ultrasim::imaging
