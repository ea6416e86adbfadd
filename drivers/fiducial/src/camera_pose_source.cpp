#include "ultrasim/drivers/fiducial/camera_pose_source.hpp"

namespace ultrasim::drivers::fiducial {

namespace {

// How long the thread waits for a frame before it looks at its stop flag again.
constexpr hal::TimestampUs kFrameWaitUs = 50'000;
// Frame period assumed before two frames have been seen (a 30 Hz camera).
constexpr double kDefaultPeriodUs = 33'333.0;

}  // namespace

CameraPoseSource::CameraPoseSource(hal::FrameSource& frames, std::unique_ptr<CameraTracker> tracker,
                                   const hal::Clock& clock, std::string name, Threading threading)
    : frames_(frames),
      tracker_(std::move(tracker)),
      clock_(clock),
      name_(std::move(name)),
      threading_(threading) {
  status_text_.reserve(160);
  if (threading_ == Threading::kOwnThread) thread_ = std::thread([this] { run(); });
}

CameraPoseSource::~CameraPoseSource() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void CameraPoseSource::run() {
  hal::CameraFrame frame;
  while (!stop_.load(std::memory_order_acquire)) {
    if (frames_.next_frame(frame, kFrameWaitUs)) {
      process(frame);
    } else {
      note_no_frame();
    }
  }
}

void CameraPoseSource::note_no_frame() {
  const auto health = frames_.health();
  std::lock_guard lock(mutex_);
  status_.camera = health;
  status_.camera_status = std::string(frames_.status());
}

void CameraPoseSource::process(const hal::CameraFrame& frame) {
  const hal::TimestampUs start_us = clock_.now_us();
  const TrackResult result = tracker_->track(frame);
  const double took_us = static_cast<double>(clock_.now_us() - start_us);
  std::lock_guard lock(mutex_);
  if (last_frame_us_ > 0 && frame.timestamp_us > last_frame_us_) {
    const double period = static_cast<double>(frame.timestamp_us - last_frame_us_);
    status_.frame_period_us =
        status_.frame_period_us > 0.0 ? 0.9 * status_.frame_period_us + 0.1 * period : period;
  }
  status_.track_us = status_.track_us > 0.0 ? 0.9 * status_.track_us + 0.1 * took_us : took_us;
  last_frame_us_ = frame.timestamp_us;
  status_.camera = frames_.health();
  status_.camera_status.clear();
  status_.counters = tracker_->counters();
  status_.last_status = result.status;
  if (result.patient_from_probe) {
    hal::PoseSample sample;
    sample.timestamp_us = frame.timestamp_us;
    sample.sequence = sequence_++;
    sample.position_mm = result.patient_from_probe->translation();
    sample.orientation = Eigen::Quaterniond(result.patient_from_probe->linear()).normalized();
    sample.health = hal::PoseHealth::kOk;
    if (hal::is_valid(sample)) last_good_ = sample;
  }
  frames_done_.fetch_add(1, std::memory_order_acq_rel);
}

std::optional<hal::PoseSample> CameraPoseSource::latest(hal::TimestampUs now_us) {
  if (threading_ == Threading::kCallerThread) {
    // Every frame due by now, in order (the filter needs each); none: say why.
    bool any = false;
    while (frames_.next_frame(caller_frame_, 0)) {
      process(caller_frame_);
      any = true;
    }
    if (!any) note_no_frame();
  }
  std::lock_guard lock(mutex_);
  status_text_.clear();
  const double period_us =
      status_.frame_period_us > 0.0 ? status_.frame_period_us : kDefaultPeriodUs;
  const bool fault = status_.camera == hal::FrameSourceHealth::kFault;
  const bool stale =
      !last_good_ || static_cast<double>(now_us - last_good_->timestamp_us) > 3.0 * period_us;
  if (fault) {
    status_text_.append("camera: ").append(status_.camera_status);
  } else if (stale) {
    if (status_.camera == hal::FrameSourceHealth::kEnded) {
      status_text_.append("camera: ").append(status_.camera_status);
    } else if (status_.counters.frames == 0) {
      status_text_.append("camera: waiting for frames");
    } else if (status_.last_status == TrackStatus::kTracked) {
      status_text_.append("camera: frames late");  // the tracker has fallen behind
    } else {
      status_text_.append("camera: ").append(to_string(status_.last_status));
    }
  }
  if (!last_good_) return std::nullopt;
  hal::PoseSample sample = *last_good_;
  if (fault) {
    sample.health = hal::PoseHealth::kFault;
  } else if (stale) {
    sample.health = hal::PoseHealth::kStale;
  }
  return sample;
}

CameraTrackingStatus CameraPoseSource::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

}  // namespace ultrasim::drivers::fiducial
