#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::camera {

struct ImageSequenceSettings {
  // Frames a second to deliver them at, on the clock; 0: each as soon as it is asked for.
  double frames_per_second = 0.0;
  // Start again from the first image after the last (a demo loop); otherwise the source ends.
  bool loop = false;
};

// A camera played back from image files (PNG, JPEG, PGM/PPM, BMP; colour is turned to grey), in
// file-name order: recorded sessions, test photographs, rendered views. A file that cannot be
// read is skipped and counted, and status() names it; the others still play.
class ImageSequenceSource final : public hal::FrameSource {
 public:
  // `images`: a folder (its image files, by name) or a list of files. Throws
  // std::invalid_argument naming the path when the folder holds no image or a file is missing.
  // `clock` timestamps the frames and paces them; it must outlive the source.
  ImageSequenceSource(const std::filesystem::path& folder, const hal::Clock& clock,
                      const ImageSequenceSettings& settings = {});
  ImageSequenceSource(std::vector<std::filesystem::path> files, const hal::Clock& clock,
                      const ImageSequenceSettings& settings = {});

  // Decodes the next image (allocates). Paced: waits (sleeping) until the frame is due when
  // frames_per_second > 0, at most timeout_us, and stamps it with its slot on the schedule; a
  // frame asked for more than half a period late is served at once and the schedule starts
  // again from it (no catching up).
  bool next_frame(hal::CameraFrame& frame, hal::TimestampUs timeout_us) override;
  hal::FrameSourceHealth health() const override { return health_; }
  std::string_view status() const override { return status_; }
  std::string_view name() const override { return name_; }

  const std::vector<std::filesystem::path>& files() const { return files_; }
  std::uint64_t unreadable_files() const { return unreadable_; }

 private:
  std::vector<std::filesystem::path> files_;
  const hal::Clock& clock_;
  ImageSequenceSettings settings_;
  std::string name_;
  std::string status_;
  hal::FrameSourceHealth health_ = hal::FrameSourceHealth::kOk;
  std::size_t next_ = 0;
  std::uint32_t sequence_ = 0;
  hal::TimestampUs next_due_us_ = -1;  // when the next frame is due; -1: not started
  std::uint64_t unreadable_ = 0;
};

// Whether the path names a file this source can read, by its extension.
bool is_image_file(const std::filesystem::path& path);

}  // namespace ultrasim::drivers::camera
