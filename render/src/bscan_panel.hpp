#pragma once

// The right panel's 2D parts (its black background is a scissored clear): title strip, depth scale
// in cm, lateral ticks, frozen tag and the no-contact / no-image states. The B-scan texture itself
// is drawn by the SceneRenderer between the background and this overlay. Internal to render/.

#include "color_batch.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/render/scene_layout.hpp"

namespace ultrasim::render::detail {

enum class BscanState {
  kImage,      // in contact with a drawable image: show it
  kNoContact,  // the probe is off the skin
  kNoImage,    // in contact but the view holds no whole image (empty or inconsistent)
};

BscanState bscan_state(const BscanView& bscan);

// Adds everything drawn over the image. depth_mm: the axial extent the scale shows.
void add_bscan_overlay(const FrameInput& frame, const ScreenLayout& layout, BscanState state,
                       float depth_mm, ColorBatch& over);

}  // namespace ultrasim::render::detail
