#include "ultrasim/drivers/camera/image_sequence.hpp"

#include <algorithm>
#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <thread>

#include "grey_frame.hpp"

namespace ultrasim::drivers::camera {

namespace {

std::vector<std::filesystem::path> images_in(const std::filesystem::path& folder) {
  std::error_code error;
  if (!std::filesystem::is_directory(folder, error)) {
    throw std::invalid_argument(folder.string() + ": not a folder of images");
  }
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.is_regular_file() && is_image_file(entry.path())) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    throw std::invalid_argument(folder.string() +
                                ": holds no image (.png, .jpg, .jpeg, .pgm, .ppm, .bmp)");
  }
  return files;
}

}  // namespace

bool is_image_file(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".pgm" || ext == ".ppm" ||
         ext == ".bmp";
}

ImageSequenceSource::ImageSequenceSource(const std::filesystem::path& folder,
                                         const hal::Clock& clock,
                                         const ImageSequenceSettings& settings)
    : ImageSequenceSource(images_in(folder), clock, settings) {
  name_ = "images:" + folder.string();
}

ImageSequenceSource::ImageSequenceSource(std::vector<std::filesystem::path> files,
                                         const hal::Clock& clock,
                                         const ImageSequenceSettings& settings)
    : files_(std::move(files)), clock_(clock), settings_(settings) {
  if (files_.empty()) throw std::invalid_argument("image sequence: no files");
  for (const auto& f : files_) {
    std::error_code error;
    if (!std::filesystem::is_regular_file(f, error)) {
      throw std::invalid_argument(f.string() + ": no such image file");
    }
  }
  if (!(settings.frames_per_second >= 0.0 && settings.frames_per_second <= 10'000.0)) {
    throw std::invalid_argument("image sequence: frames_per_second must be in [0, 10000]");
  }
  name_ = "images:" + files_.front().parent_path().string();
}

bool ImageSequenceSource::next_frame(hal::CameraFrame& frame, hal::TimestampUs timeout_us) {
  while (health_ == hal::FrameSourceHealth::kOk) {
    if (next_ == files_.size()) {
      if (!settings_.loop) {
        health_ = hal::FrameSourceHealth::kEnded;
        status_ = "ended after " + std::to_string(files_.size()) + " images";
        return false;
      }
      next_ = 0;
    }
    hal::TimestampUs captured_us = -1;
    if (settings_.frames_per_second > 0.0) {
      const hal::TimestampUs now = clock_.now_us();
      if (next_due_us_ < 0) next_due_us_ = now;
      const hal::TimestampUs wait_us = next_due_us_ - now;
      if (wait_us > timeout_us) {
        std::this_thread::sleep_for(
            std::chrono::microseconds(std::max<hal::TimestampUs>(timeout_us, 0)));
        return false;
      }
      if (wait_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(wait_us));
      // Stamped at its slot, as a camera stamps its exposure (a sleep's oversleep does not slow
      // the rate); a frame served more than half a period late starts the schedule again from
      // now, so the ones after it keep the rate instead of coming in a burst to catch up.
      const auto period_us = static_cast<hal::TimestampUs>(1e6 / settings_.frames_per_second);
      const hal::TimestampUs served_us = clock_.now_us();
      if (served_us - next_due_us_ > period_us / 2) next_due_us_ = served_us;
      captured_us = next_due_us_;
      next_due_us_ += period_us;
    }
    const std::filesystem::path& file = files_[next_++];
    const cv::Mat grey = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (grey.empty()) {
      ++unreadable_;
      status_ = file.string() + ": cannot be read as an image (skipped)";
      continue;
    }
    frame.timestamp_us = captured_us >= 0 ? captured_us : clock_.now_us();
    frame.sequence = sequence_++;
    detail::copy_grey(grey, frame);
    return true;
  }
  return false;
}

}  // namespace ultrasim::drivers::camera
