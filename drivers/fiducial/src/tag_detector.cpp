#include "ultrasim/drivers/fiducial/tag_detector.hpp"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

#include <algorithm>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace ultrasim::drivers::fiducial {

struct TagDetector::Impl {
  apriltag_family_t* family = nullptr;
  void (*destroy_family)(apriltag_family_t*) = nullptr;
  apriltag_detector_t* detector = nullptr;
  cv::Ptr<cv::CLAHE> equaliser;  // null when off
  cv::Mat enlarged;              // the searched region after upsampling, reused
  cv::Mat equalised;             // ... and after equalising, reused
};

TagDetector::TagDetector(const TagDetectorSettings& settings)
    : settings_(settings), impl_(std::make_unique<Impl>()) {
  const auto bad = [](const std::string& what) {
    throw std::invalid_argument("tag detector: " + what);
  };
  if (!(settings.quad_decimate >= 1.0 && settings.quad_decimate <= 8.0))
    bad("quad_decimate must be in [1, 8]");
  if (!(settings.quad_sigma >= 0.0 && settings.quad_sigma <= 5.0))
    bad("quad_sigma must be in [0, 5]");
  if (settings.max_hamming < 0 || settings.max_hamming > 3) bad("max_hamming must be in [0, 3]");
  if (!(settings.upsample >= 1.0 && settings.upsample <= 4.0)) bad("upsample must be in [1, 4]");
  if (!(settings.equalise_clip_limit >= 0.0 && settings.equalise_clip_limit <= 40.0))
    bad("equalise_clip_limit must be in [0, 40]");
  if (settings.equalise_clip_limit > 0.0) {
    impl_->equaliser = cv::createCLAHE(settings.equalise_clip_limit, cv::Size(8, 8));
  }
  if (settings.family == "tag36h11") {
    impl_->family = tag36h11_create();
    impl_->destroy_family = tag36h11_destroy;
  } else if (settings.family == "tagStandard41h12") {
    impl_->family = tagStandard41h12_create();
    impl_->destroy_family = tagStandard41h12_destroy;
  } else {
    bad("unknown family '" + settings.family + "'; allowed: tag36h11, tagStandard41h12");
  }
  impl_->detector = apriltag_detector_create();
  // AprilTag builds its decoding table for up to this many bit errors.
  apriltag_detector_add_family_bits(impl_->detector, impl_->family, settings.max_hamming);
  impl_->detector->quad_decimate = static_cast<float>(settings.quad_decimate);
  impl_->detector->quad_sigma = static_cast<float>(settings.quad_sigma);
  impl_->detector->nthreads = 1;  // its worker pool is unsafe: see the class comment
  impl_->detector->refine_edges = settings.refine_edges;
  impl_->detector->decode_sharpening = settings.decode_sharpening;
}

TagDetector::~TagDetector() {
  if (impl_->detector) apriltag_detector_destroy(impl_->detector);
  if (impl_->family) impl_->destroy_family(impl_->family);
}

std::vector<TagDetection> TagDetector::detect(const hal::CameraFrame& frame, PixelRegion region) {
  std::vector<TagDetection> out;
  if (frame.width <= 0 || frame.height <= 0 ||
      frame.grey.size() < static_cast<std::size_t>(frame.width) * frame.height) {
    return out;
  }
  if (region.empty()) region = {0, 0, frame.width, frame.height};
  const int x0 = std::clamp(region.x, 0, frame.width);
  const int y0 = std::clamp(region.y, 0, frame.height);
  const int x1 = std::clamp(region.x + region.width, 0, frame.width);
  const int y1 = std::clamp(region.y + region.height, 0, frame.height);
  // Too small to hold a tag the decimated search can see.
  if (x1 - x0 < 16 || y1 - y0 < 16) return out;
  // A view into the frame: AprilTag reads rows `stride` apart, so the region needs no copy
  // unless it is equalised first.
  std::uint8_t* pixels = const_cast<std::uint8_t*>(frame.grey.data()) +
                         static_cast<std::ptrdiff_t>(y0) * frame.width + x0;
  cv::Mat searched(y1 - y0, x1 - x0, CV_8UC1, pixels, static_cast<std::size_t>(frame.width));
  const double scale = settings_.upsample;
  if (scale > 1.0) {
    cv::resize(searched, impl_->enlarged, cv::Size(), scale, scale, cv::INTER_LINEAR);
    searched = impl_->enlarged;
  }
  if (impl_->equaliser) {
    impl_->equaliser->apply(searched, impl_->equalised);
    searched = impl_->equalised;
  }
  image_u8_t view{searched.cols, searched.rows, static_cast<std::int32_t>(searched.step),
                  searched.data};
  zarray_t* found = apriltag_detector_detect(impl_->detector, &view);
  for (int i = 0; i < zarray_size(found); ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(found, i, &d);
    if (d->hamming > settings_.max_hamming || d->decision_margin < settings_.min_decision_margin) {
      continue;
    }
    TagDetection t;
    t.id = d->id;
    t.hamming = d->hamming;
    t.decision_margin = d->decision_margin;
    // AprilTag puts pixel centres at +0.5 (measured: its corners sit half a pixel right of and
    // below the true ones on rendered views), so its coordinates scale from the pixels' edges;
    // CameraFrame's centres are at the integers.
    for (int k = 0; k < 4; ++k) {
      t.corners_px[k] = {d->p[k][0] / scale + x0 - 0.5, d->p[k][1] / scale + y0 - 0.5};
    }
    out.push_back(t);
  }
  apriltag_detections_destroy(found);
  return out;
}

}  // namespace ultrasim::drivers::fiducial
