#pragma once

#include <stdexcept>

namespace ultrasim::render {

// A display back end could not be brought up or used: no EGL display, no GLES 3 context, an
// incomplete framebuffer. what() is one line naming the failing call and its error code, with a
// hint where the usual cause is known (e.g. the Mesa software driver not installed).
class DisplayError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace ultrasim::render
