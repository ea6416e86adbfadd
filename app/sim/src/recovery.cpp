#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {

std::string_view recovery_key(Recovery recovery) {
  switch (recovery) {
    case Recovery::kNone:
      return "none";
    case Recovery::kSubstepped:
      return "substepped";
    case Recovery::kReset:
      return "reset";
    case Recovery::kKeptLastGood:
      return "kept-last-good";
  }
  return "unknown";
}

std::string_view cause_key(DivergenceCause cause) {
  switch (cause) {
    case DivergenceCause::kNone:
      return "none";
    case DivergenceCause::kNonFinite:
      return "non-finite";
    case DivergenceCause::kEnergy:
      return "energy";
    case DivergenceCause::kRunaway:
      return "runaway";
    case DivergenceCause::kInverted:
      return "inverted";
    case DivergenceCause::kSeamTorn:
      return "seam-torn";
  }
  return "unknown";
}

Recovery worse_recovery(Recovery a, Recovery b) {
  const auto severity = [](Recovery r) {
    switch (r) {
      case Recovery::kNone:
        return 0;
      case Recovery::kSubstepped:
        return 1;
      case Recovery::kKeptLastGood:
        return 2;
      case Recovery::kReset:
        return 3;
    }
    return 0;
  };
  return severity(a) >= severity(b) ? a : b;
}

}  // namespace ultrasim::sim
