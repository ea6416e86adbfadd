#include "ultrasim/drivers/camera/v4l2_camera.hpp"

#include <chrono>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <thread>

#include "grey_frame.hpp"

namespace ultrasim::drivers::camera {

struct V4l2CameraSource::Impl {
  cv::VideoCapture capture;
  cv::Mat image;
  cv::Mat grey;
};

V4l2CameraSource::V4l2CameraSource(const V4l2CameraSettings& settings, const hal::Clock& clock)
    : impl_(std::make_unique<Impl>()), settings_(settings), clock_(clock) {
  open();
}

V4l2CameraSource::~V4l2CameraSource() = default;

bool V4l2CameraSource::open() {
  tried_ = true;
  last_open_attempt_us_ = clock_.now_us();
  impl_->capture.release();
  if (!impl_->capture.open(settings_.device, cv::CAP_V4L2)) {
    health_ = hal::FrameSourceHealth::kFault;
    status_ = settings_.device + ": cannot open (no such camera, or in use); retrying";
    return false;
  }
  impl_->capture.set(cv::CAP_PROP_FRAME_WIDTH, settings_.width_px);
  impl_->capture.set(cv::CAP_PROP_FRAME_HEIGHT, settings_.height_px);
  impl_->capture.set(cv::CAP_PROP_FPS, settings_.frames_per_second);
  health_ = hal::FrameSourceHealth::kOk;
  status_.clear();
  return true;
}

bool V4l2CameraSource::next_frame(hal::CameraFrame& frame, hal::TimestampUs timeout_us) {
  if (health_ != hal::FrameSourceHealth::kOk) {
    const hal::TimestampUs since = clock_.now_us() - last_open_attempt_us_;
    if (tried_ && since < settings_.reopen_interval_us) {
      // Nothing to read: wait out the caller's timeout rather than spin.
      std::this_thread::sleep_for(
          std::chrono::microseconds(std::min(timeout_us, settings_.reopen_interval_us - since)));
      return false;
    }
    if (!open()) return false;
  }
  if (!impl_->capture.read(impl_->image) || impl_->image.empty()) {
    health_ = hal::FrameSourceHealth::kFault;
    status_ = settings_.device + ": stopped delivering frames (unplugged?); retrying";
    impl_->capture.release();
    return false;
  }
  frame.timestamp_us = clock_.now_us();
  frame.sequence = sequence_++;
  const cv::Mat* grey = &impl_->image;
  if (impl_->image.channels() == 3) {
    cv::cvtColor(impl_->image, impl_->grey, cv::COLOR_BGR2GRAY);
    grey = &impl_->grey;
  } else if (impl_->image.channels() == 4) {
    cv::cvtColor(impl_->image, impl_->grey, cv::COLOR_BGRA2GRAY);
    grey = &impl_->grey;
  }
  detail::copy_grey(*grey, frame);
  return true;
}

}  // namespace ultrasim::drivers::camera
