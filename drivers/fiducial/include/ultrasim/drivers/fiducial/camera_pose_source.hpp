#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "ultrasim/drivers/fiducial/camera_tracker.hpp"
#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/hal/pose_source.hpp"

namespace ultrasim::drivers::fiducial {

// What the tracking thread has done, for the stats overlay, the bring-up screen and the log.
struct CameraTrackingStatus {
  TrackerCounters counters;
  TrackStatus last_status = TrackStatus::kNoMarkers;
  hal::FrameSourceHealth camera = hal::FrameSourceHealth::kOk;
  std::string camera_status;     // the frame source's own words while it is not ok
  double frame_period_us = 0.0;  // measured, averaged
  double track_us = 0.0;         // time to track one frame, averaged
};

// The camera tracker as a probe pose source: a thread takes frames from `frames` as they come,
// tracks each, and leaves the newest tracked pose in a mailbox that latest() reads (or, for a
// recording played on a virtual clock, latest() itself tracks the frames due by then, so a
// headless run is the same on every machine). Health: ok
// while frames keep being tracked; stale (the last good pose held) once no frame has been
// tracked for 3 frame periods; fault when the camera fails or goes away (unplugged), with the
// last good pose held.
class CameraPoseSource final : public hal::PoseSource {
 public:
  enum class Threading : std::uint8_t {
    kOwnThread,     // a live camera: tracked as frames come, beside the frame thread
    kCallerThread,  // a recording on a virtual clock: tracked in latest(), deterministically
  };

  // Starts the tracking thread (kOwnThread). `frames` and `clock` must outlive this object;
  // `clock` must be the frames' time line (the tracking times its work on it).
  CameraPoseSource(hal::FrameSource& frames, std::unique_ptr<CameraTracker> tracker,
                   const hal::Clock& clock, std::string name = "camera",
                   Threading threading = Threading::kOwnThread);
  ~CameraPoseSource() override;  // stops and joins the thread
  CameraPoseSource(const CameraPoseSource&) = delete;
  CameraPoseSource& operator=(const CameraPoseSource&) = delete;

  // Frame thread. kOwnThread: non-blocking (a short lock), no allocation; kCallerThread: tracks
  // the frames due (allocates).
  std::optional<hal::PoseSample> latest(hal::TimestampUs now_us) override;
  std::string_view name() const override { return name_; }
  // While the pose is not fresh: the camera's fault, or why the last frame was not tracked.
  std::string_view status_text() const override { return status_text_; }

  // Any thread. Allocates (the status text).
  CameraTrackingStatus status() const;

  // Frames tracked so far (tests wait on it).
  std::uint64_t frames_done() const { return frames_done_.load(std::memory_order_acquire); }

 private:
  void run();
  // Tracks one frame and publishes the result; mutex_ must not be held.
  void process(const hal::CameraFrame& frame);
  // Notes why no frame came; mutex_ must not be held.
  void note_no_frame();

  hal::FrameSource& frames_;
  std::unique_ptr<CameraTracker> tracker_;
  const hal::Clock& clock_;
  std::string name_;
  Threading threading_;
  hal::CameraFrame caller_frame_;  // kCallerThread's buffer
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> frames_done_{0};

  mutable std::mutex mutex_;  // guards what follows
  std::optional<hal::PoseSample> last_good_;
  std::string status_text_;  // the frame thread's copy, set by latest(); reserved
  hal::TimestampUs last_frame_us_ = 0;
  std::uint32_t sequence_ = 0;
  CameraTrackingStatus status_;

  std::thread thread_;  // last: starts (kOwnThread) once everything above exists
};

}  // namespace ultrasim::drivers::fiducial
