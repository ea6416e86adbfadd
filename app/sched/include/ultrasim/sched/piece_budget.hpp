#pragma once

// The budget a task's stoppable work asks before each piece (a method's CG iterations, contact
// rounds, sub-volumes left for later): another piece starts only while one as long as the last
// still ends by the task's deadline, less the tail kept back. The tail is what the work went on
// doing after its first "no" the last time it was told one: work that stops at a "no" does not
// always end there (an implicit MSDS told no in its first step still runs its second step's
// forces, set-up and one iteration: 1.7 ms past a 4 ms share, every frame). Time comes only
// from the injected hal::Clock.

#include <cstdint>

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::sched {

class PieceBudget {
 public:
  // kTailAndPiece: the tail kept back and the first question's piece as described at start()
  // (the kiosk's one-piece methods). kNothing: each question measured from the one before (the
  // first from the start) and nothing kept back, for work that plans its time itself (a
  // stitched volume shares its time over its batches and keeps their tails back; given its last
  // frame's piece at the first question, the large case's seams opened 0.16-0.19 mm, 0.10 as it
  // plans).
  enum class Memory { kTailAndPiece, kNothing };

  // `clock` must outlive this.
  explicit PieceBudget(const hal::Clock& clock) : clock_(clock) {}

  // The work starts: pieces may run until `deadline_us`. A piece is the work between a "yes"
  // and the next question; later questions take the last piece's length. The first takes the
  // shortest piece of the last work that measured one, if no longer than the time since
  // `measured_from_us` (the task's start), else that time. The work before the first question
  // is no piece: so measured, with a tail kept back, it told the implicit MSDS no after one
  // iteration of its first step. `memory`: what the start takes from earlier work.
  void start(hal::TimestampUs measured_from_us, hal::TimestampUs deadline_us,
             Memory memory = Memory::kTailAndPiece);

  // Whether another piece as long as the last still ends by the deadline with the tail kept
  // back.
  bool may_start_another();

  // The work is done: what it did after its first "no" (if it was told one) is the tail kept
  // back from the next start's deadline, and its shortest piece the next first question's.
  // Work told nothing leaves the last tail as it was; work that measured no piece, the piece,
  // but for work told no at its first question: half the piece that question took, so that a
  // piece is measured again once one fits.
  void finish();

  std::int64_t time_left_us() const { return deadline_us_ - clock_.now_us(); }
  std::int64_t tail_us() const { return tail_us_; }
  // Forgets the tail and the piece measured (the work changed: another method).
  void forget_measures() {
    tail_us_ = 0;
    piece_us_ = frame_piece_us_ = -1;
  }

 private:
  const hal::Clock& clock_;
  hal::TimestampUs deadline_us_ = 0;
  hal::TimestampUs last_question_us_ = 0;
  bool asked_ = false;          // since start()
  bool last_said_yes_ = false;  // the last question since start()
  // The shortest piece of the last work that measured one, and of this one (-1: none yet). The
  // shortest: a piece that spans the end of one step and the start of the next (its forces, its
  // set-up) is not the piece the next first question is about.
  std::int64_t piece_us_ = -1;
  std::int64_t frame_piece_us_ = -1;
  std::int64_t first_piece_us_ = 0;    // what this work's first question took its piece to be
  bool first_said_no_ = false;         // this work's first question
  hal::TimestampUs first_no_us_ = -1;  // -1: not told no since start()
  std::int64_t tail_us_ = 0;
  Memory memory_ = Memory::kTailAndPiece;
};

}  // namespace ultrasim::sched
