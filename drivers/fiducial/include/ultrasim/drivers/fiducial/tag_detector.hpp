#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "ultrasim/hal/camera_frame.hpp"

namespace ultrasim::drivers::fiducial {

// How AprilTag searches an image. Defaults suit a 640×480 camera watching the probe's
// dodecahedron at 0.3–0.6 m.
struct TagDetectorSettings {
  // The marker family: "tag36h11" (the dodecahedron's) or "tagStandard41h12".
  std::string family = "tag36h11";
  // Quads are found on an image this many times smaller (1 = full resolution). 2 roughly quarters
  // the search's cost but loses the dodecahedron's steep faces (~20 px across at 0.4 m: on
  // rendered views it found 113 of the 157 tags full resolution finds); corners are refined at
  // full resolution when refine_edges is on, so accuracy is kept. The tracker searches only
  // around the body once it has it, which pays for the full resolution.
  double quad_decimate = 1.0;
  // Gaussian blur (pixels) before the quad search; 0 = none. Helps noisy images, costs time.
  double quad_sigma = 0.0;
  // Snap each quad's edges to the image's gradients at full resolution. Costs ~10 %; without it
  // a decimated search's corners are off by up to a pixel.
  bool refine_edges = true;
  // Sharpening of the decoded bits (AprilTag's default 0.25): helps small, blurred tags.
  double decode_sharpening = 0.25;
  // The searched region is enlarged this many times (bilinear) before the search: AprilTag
  // thresholds in 4-pixel tiles, too coarse for the white ring of a face seen at a steep angle
  // (~2 px across at 0.35 m). On rendered views 1.5 found tags 1 did not. Costs its square in
  // time; the tracker searches only around the body, which pays for it.
  double upsample = 1.5;
  // Contrast-limited adaptive histogram equalisation (CLAHE) of the searched region first, with
  // this clip limit (0 = off); 8 × 8 tiles. Faces turned from the light are dim: on rendered
  // views, equalising found their tags where the plain search found none. Costs ~1 ms at
  // 640 × 480.
  double equalise_clip_limit = 2.0;
  // Detections with more corrected bits than this are dropped (tag36h11 corrects up to 3, but
  // each corrected bit makes a false id likelier).
  int max_hamming = 1;
  // Detections whose decoding margin is below this are dropped: weak ones are mostly glare or
  // texture that happened to decode.
  double min_decision_margin = 15.0;
};

// One tag found in an image. Corners in pixels (CameraFrame's convention), in the order of
// hal::BodyMarker's corners.
struct TagDetection {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;
  int hamming = 0;
  double decision_margin = 0.0;
};

// A rectangle of the image to search, in pixels; the whole image when empty.
struct PixelRegion {
  int x = 0, y = 0, width = 0, height = 0;
  bool empty() const { return width <= 0 || height <= 0; }
};

// AprilTag's detector for one family. Not thread-safe: one per tracking thread. It runs on the
// caller's thread only: AprilTag 3.3's own worker pool (Debian 12's) can call a task through a
// pointer into an array another thread is reallocating (fixed upstream in AprilRobotics/apriltag
// pull request 339); with two workers, 2 of 12 runs of the accuracy test crashed, three at once.
class TagDetector {
 public:
  // Throws std::invalid_argument naming the setting that is out of range or the family unknown.
  explicit TagDetector(const TagDetectorSettings& settings);
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // The tags in `frame` (only inside `region`, clipped to the image, when given). Allocates.
  std::vector<TagDetection> detect(const hal::CameraFrame& frame, PixelRegion region = {});

  const TagDetectorSettings& settings() const { return settings_; }

 private:
  struct Impl;
  TagDetectorSettings settings_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ultrasim::drivers::fiducial
