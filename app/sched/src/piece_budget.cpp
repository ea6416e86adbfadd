#include "ultrasim/sched/piece_budget.hpp"

#include <algorithm>

namespace ultrasim::sched {

void PieceBudget::start(hal::TimestampUs measured_from_us, hal::TimestampUs deadline_us,
                        Memory memory) {
  deadline_us_ = deadline_us;
  last_question_us_ = measured_from_us;
  asked_ = false;
  last_said_yes_ = false;
  frame_piece_us_ = -1;
  first_no_us_ = -1;
  memory_ = memory;
}

bool PieceBudget::may_start_another() {
  const hal::TimestampUs now = clock_.now_us();
  const std::int64_t since_last_us = now - last_question_us_;
  last_question_us_ = now;
  // Only the work after a "yes" is a piece: after a "no" it is the tail (an implicit MSDS's next
  // step, taken as a piece, told the next frame's first question no).
  if (last_said_yes_) {
    frame_piece_us_ =
        frame_piece_us_ < 0 ? since_last_us : std::min(frame_piece_us_, since_last_us);
  }
  // The first question: no longer than the work so far, so that one slow piece (a hiccup) is not
  // taken for the next frames' (it told them all no at their first question, and a frame told
  // no there measures no piece).
  const bool remembered = !asked_ && piece_us_ >= 0 && memory_ == Memory::kTailAndPiece;
  const std::int64_t last_piece_us =
      remembered ? std::min(piece_us_, since_last_us) : since_last_us;
  asked_ = true;
  const std::int64_t kept_back_us = memory_ == Memory::kTailAndPiece ? tail_us_ : 0;
  // A piece that would end on the deadline fits; none starts once it is reached.
  last_said_yes_ = now < deadline_us_ && now + last_piece_us + kept_back_us <= deadline_us_;
  if (!last_said_yes_ && first_no_us_ < 0) first_no_us_ = now;
  return last_said_yes_;
}

void PieceBudget::finish() {
  if (memory_ == Memory::kNothing) return;
  if (frame_piece_us_ >= 0) piece_us_ = frame_piece_us_;
  if (first_no_us_ >= 0) tail_us_ = std::max<std::int64_t>(clock_.now_us() - first_no_us_, 0);
}

}  // namespace ultrasim::sched
