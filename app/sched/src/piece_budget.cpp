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
  first_said_no_ = false;
  memory_ = memory;
}

bool PieceBudget::may_start_another() {
  const hal::TimestampUs now = clock_.now_us();
  const std::int64_t since_last_us = now - last_question_us_;
  last_question_us_ = now;
  const bool first = !asked_;
  asked_ = true;
  // Only the work after a "yes" is a piece: after a "no" it is the tail (an implicit MSDS's next
  // step, taken as a piece, told the next frame's first question no).
  if (last_said_yes_) {
    frame_piece_us_ =
        frame_piece_us_ < 0 ? since_last_us : std::min(frame_piece_us_, since_last_us);
  }
  // The first question: no longer than the work so far (one slow piece, a hiccup, told the next
  // frames no at their first question).
  const bool remembered = first && piece_us_ >= 0 && memory_ == Memory::kTailAndPiece;
  const std::int64_t last_piece_us =
      remembered ? std::min(piece_us_, since_last_us) : since_last_us;
  if (first) first_piece_us_ = last_piece_us;
  const std::int64_t kept_back_us = memory_ == Memory::kTailAndPiece ? tail_us_ : 0;
  // A piece that would end on the deadline fits; none starts once it is reached.
  last_said_yes_ = now < deadline_us_ && now + last_piece_us + kept_back_us <= deadline_us_;
  if (!last_said_yes_ && first_no_us_ < 0) {
    first_no_us_ = now;
    first_said_no_ = first;
  }
  return last_said_yes_;
}

void PieceBudget::finish() {
  if (memory_ == Memory::kNothing) return;
  // Told no at its first question, the work measured no piece, and would never measure one if
  // the next frames took the same: their first question told no, one iteration a step for good
  // (the default case's implicit MSDS, its first question after 1.7 ms of fixed work). The
  // estimate halves each such frame until a piece fits and is measured.
  if (frame_piece_us_ >= 0) {
    piece_us_ = frame_piece_us_;
  } else if (first_said_no_) {
    piece_us_ = first_piece_us_ / 2;
  }
  // The tail goes up at once and down a quarter of the way a frame: it varies from frame to frame
  // (the implicit MSDS's second step starts from its first's velocity only where that lowers its
  // energy, and the test takes one more product), and a frame whose tail is longer than the last
  // one's runs late by the difference (the default case's sweep-press: 201 and 279 of 571 frames
  // past the 4 ms share kept from the last frame alone, 87-212 so; most by less than 0.1 ms).
  if (first_no_us_ >= 0) {
    const std::int64_t tail_us = std::max<std::int64_t>(clock_.now_us() - first_no_us_, 0);
    tail_us_ = std::max(tail_us, tail_us_ - tail_us_ / 4);
  }
}

}  // namespace ultrasim::sched
