#pragma once

// Where the tissue is pressed while its method refuses the probe's pose (a press too deep for
// it, a seam torn open, tets inverted past its limit). The method then shows its last good
// shape; trying the same pose again every frame would cost a frame's work each time to show
// that shape again. Instead the tissue is pressed where it last took the probe, and
// - a try toward the probe's pose is made a few times a second, part of the way: a try the
//   tissue takes is followed the next frame by one going further, one it refuses by one going
//   half as far (the next frame after a taken one, else after the wait): the tissue follows as
//   deep as its method lets it, and catches up with a probe that moved on;
// - while the tissue refuses even that held pose (its unfinished solve creeps on into a shape
//   the method refuses), the held pose backs off along the beam, twice as far each time (64 mm
//   at most in all), until the tissue takes it: a refused frame leaves the tissue somewhere it
//   can go on from.
// Lifting the probe off the refused depth (or off the depth the tissue is pressed to, if deeper)
// tries its own pose at once: the tissue must not stay pressed by a probe that has left.

#include <optional>

#include "ultrasim/hal/pose_sample.hpp"
#include "ultrasim/sim/engine.hpp"

namespace ultrasim::kiosk {

// A frame's outcome for the pose the tissue was pressed with.
enum class PressVerdict {
  kTaken,      // the method's frame stands (re-run in smaller steps or not)
  kRefused,    // the method refused the pose and kept its last good shape
  kOutOfTime,  // it kept its last good shape because the frame's time ran out before smaller
               // steps were tried: on the probe's own pose, no verdict the first time (the next
               // frame tries it again) and a refusal the second in a row; on a held pose or a
               // try part of the way, a refusal
  kUndecided,  // it failed otherwise (reset to rest): no verdict
};

// The verdict a method's frame stats give.
PressVerdict verdict_of(const sim::EngineStepStats& step);

class RefusedPress {
 public:
  // A try every this many frames while the tissue is held (four a second at 60 Hz).
  static constexpr int kRetryEveryFrames = 15;
  // The probe this far above the depth of its refused pose is tried at once, mm.
  static constexpr double kRetryAfterLiftMm = 0.5;
  // A try's first share of the way to the probe; a taken try's next goes kGrowth times as far
  // (a share of what is left), a refused one's half as far, down to kLeastReach.
  static constexpr double kFirstReach = 0.5;
  static constexpr double kGrowth = 1.5;
  static constexpr double kLeastReach = 1.0 / 64.0;
  // Within this of the probe's pose a try is the probe's own pose (mm, rad).
  static constexpr double kNearMm = 0.1;
  static constexpr double kNearRad = 0.5 * 3.14159265358979 / 180.0;
  // The held pose's first back-off along the beam when the tissue refuses it, the most one
  // back-off goes, and the most they go in all before the tissue takes a pose again, mm.
  static constexpr double kFirstBackOffMm = 0.5;
  static constexpr double kLargestBackOffMm = 8.0;
  static constexpr double kMostBackOffMm = 64.0;

  // The pose to press the tissue with this frame, given the probe's (valid, as the session's).
  const hal::PoseSample& pose_for(const hal::PoseSample& probe);
  // The method's verdict on the pose pose_for() gave this frame. A held pose refused is backed
  // off even once it no longer touches the skin: a stitched region decides which sub-volumes
  // step by the probe's reach, and a pose hovering above the skin kept stepping the same ones
  // into the same refused frame (the large soak: 126 frames); out of reach, the region relaxes
  // by its seams' pulls.
  void record(PressVerdict verdict);
  // Whether this frame's pose is not the probe's own (held, backed off or part of the way).
  bool holding() const { return attempt_ != Attempt::kProbe && !probe_pose_tried_; }
  // Back to the probe's own pose next frame (another method, or no probe pose): what the
  // tissue last took is kept, to hold if that is refused at once.
  void reset() {
    refused_ = false;
    probe_out_of_time_ = 0;
  }

 private:
  enum class Attempt { kProbe, kHeld, kToward };
  // Part of the way from the taken pose to the probe's (all of it when near: probe_pose_tried_).
  hal::PoseSample toward_probe(const hal::PoseSample& probe);

  Attempt attempt_ = Attempt::kProbe;
  hal::PoseSample pose_;                  // this frame's
  bool probe_pose_tried_ = false;         // pose_ is the probe's own (a try that reached it)
  std::optional<hal::PoseSample> taken_;  // the last pose the tissue took
  bool refused_ = false;                  // holding since a refusal
  double refused_depth_mm_ = 0.0;         // the probe's face depth (z) at it
  int frames_since_try_ = 0;
  double reach_ = kFirstReach;  // the next try's share of the way to the probe
  bool last_try_taken_ = false;
  int probe_out_of_time_ = 0;   // frames in a row the probe's own pose ran out of time
  double backed_off_mm_ = 0.0;  // since the tissue last took a pose
};

}  // namespace ultrasim::kiosk
