#pragma once

// Internal to drivers/camera: an 8-bit grey OpenCV image into a hal::CameraFrame.

#include <algorithm>
#include <cstdint>
#include <opencv2/core.hpp>

#include "ultrasim/hal/camera_frame.hpp"

namespace ultrasim::drivers::camera::detail {

// Copies `grey` (CV_8UC1, any row stride) into frame's pixels and size; reuses its buffer.
inline void copy_grey(const cv::Mat& grey, hal::CameraFrame& frame) {
  frame.width = grey.cols;
  frame.height = grey.rows;
  frame.grey.resize(static_cast<std::size_t>(grey.cols) * grey.rows);
  for (int y = 0; y < grey.rows; ++y) {
    std::copy_n(grey.ptr<std::uint8_t>(y), grey.cols,
                frame.grey.data() + static_cast<std::size_t>(y) * grey.cols);
  }
}

}  // namespace ultrasim::drivers::camera::detail
