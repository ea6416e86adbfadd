// The short soak: `ultrasim-kiosk --headless --script soak` for 40 virtual seconds over the case
// list (the default case and the PLUS spine phantom), random scanning with method and case
// switches, then its report checked against the soak's bounds (docs/benchmarks.md, "Soak"):
//   - it ends by itself, exit status 0, every frame run;
//   - no integrator blew up (a reset to rest: the engines' guard against NaN and energy growth);
//   - resident memory after the warm-up grows by at most 200 MB between the first and the last
//     quarter of the run: the exact FEM keeps the Green's functions of up to 256 nodes it meets
//     off the skin (~170 MB on the default case), which fill as the probe goes deep; a leak of
//     a few kB a frame over a long soak shows beyond that (the long soak's figures); the heap
//     in use likewise, and resident memory less the heap in use by at most 32 MB: the memory a
//     case switch frees is handed back, not kept resident by the allocator;
//   - deadline misses on at most 60 % of frames on two cores, counting each frame's rendering
//     at no more than its 9 ms reserve (report.json `frame_time_render_capped`): drawing on the
//     CPU (llvmpipe) takes 6 to 15 ms a frame depending on the host (render_bench's same scene:
//     3.7 ms on one, 11.4 ms on another), and whole frames over the budget measure that host,
//     not the schedule. The trainee's choice of method decides a frame's time (the corotational
//     FEM's fixed work exceeds its share on the default case), so the bound catches a slowdown
//     of the whole schedule, not one method's; the explicit MSDS, whose work fits, keeps its
//     median inside the budget. Whole frames are in the report and docs/benchmarks.md.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <string>

#include "report_json.hpp"

namespace {

namespace fs = std::filesystem;
using ultrasim::testing::json_number;
using ultrasim::testing::read_text;

constexpr double kSoakSeconds = 40.0;
constexpr double kFrameBudgetUs = 16'667.0;

class ShortSoak : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    out_ = fs::temp_directory_path() / ("ultrasim_soak_" + std::to_string(::getpid()));
    fs::remove_all(out_);
    const std::string command = std::string(ULTRASIM_KIOSK_EXE) +
                                " --headless --script soak --soak-seconds " +
                                std::to_string(kSoakSeconds) + " --seed 3 --case " +
                                ULTRASIM_DEFAULT_CASE + " --also-case " + ULTRASIM_PLUS_CASE +
                                " --out " + out_.string() + " > " + out_.string() + ".log 2>&1";
    status_ = std::system(command.c_str());
    report_ = read_text(out_ / "report.json");
  }
  static void TearDownTestSuite() {
    fs::remove_all(out_);
    fs::remove(out_.string() + ".log");
  }
  static inline fs::path out_;
  static inline int status_ = -1;
  static inline std::string report_;
};

TEST_F(ShortSoak, EndsByItselfHavingRunEveryFrameAndSwitchedMethodsAndCases) {
  ASSERT_TRUE(WIFEXITED(status_)) << "the kiosk crashed: " << read_text(out_.string() + ".log");
  ASSERT_EQ(WEXITSTATUS(status_), 0) << read_text(out_.string() + ".log");
  ASSERT_FALSE(report_.empty());
  EXPECT_GE(json_number(report_, "frames"), kSoakSeconds * 1e6 / kFrameBudgetUs);
  EXPECT_GE(json_number(report_, "method_switches"), 5);  // the warm-up alone makes 10
  EXPECT_GE(json_number(report_, "case_switches"), 2);    // to the spine phantom and back
  EXPECT_EQ(json_number(report_, "poses_rejected"), 0);
}

TEST_F(ShortSoak, NoIntegratorBlewUp) {
  EXPECT_EQ(json_number(report_, "reset"), 0);
}

// The recovery log (report.json `recovery_events`) accounts for every frame the counts say a
// method recovered from, kind by kind, with where and when each run of them started. (This
// seed's session may have none to log: then the log must be empty too. How runs of frames
// become events is recovery_events_test's.)
TEST_F(ShortSoak, RecoveryEventsAccountForEveryRecoveredFrame) {
  const std::size_t log = report_.find("\"recovery_events\":");
  ASSERT_NE(log, std::string::npos);
  ASSERT_EQ(json_number(report_, "dropped", log), 0);
  std::map<std::string, double> frames;
  const std::regex event(
      "\"kind\": \"([a-z-]+)\", \"cause\": \"[a-z-]+\", \"first_frame\": ([0-9]+), "
      "\"length_frames\": ([0-9]+), \"time_s\": [-0-9.eE+]+, \"case\": \"[^\"]+\", "
      "\"method\": \"[a-z-]+\"");
  for (auto it = std::sregex_iterator(report_.begin(), report_.end(), event);
       it != std::sregex_iterator(); ++it) {
    frames[(*it)[1]] += std::stod((*it)[3]);
  }
  EXPECT_EQ(frames["substepped"], json_number(report_, "substepped"));
  EXPECT_EQ(frames["kept-last-good"], json_number(report_, "kept_last_good"));
  EXPECT_EQ(frames["reset"], json_number(report_, "reset"));
}

// Every frame a method's checks failed says what they found (report.json `sim`
// `diverged_by_cause`): the causes add up to the diverged frames. (This seed's session may have
// none: then 0 = 0. How the report writes them is recovery_events_test's.)
TEST_F(ShortSoak, EveryDivergedFrameHasACause) {
  const std::size_t causes = report_.find("\"diverged_by_cause\":");
  ASSERT_NE(causes, std::string::npos);
  double sum = 0.0;
  for (const char* cause : {"non-finite", "energy", "runaway", "inverted", "seam-torn"}) {
    sum += json_number(report_, cause, causes);
  }
  EXPECT_EQ(sum, json_number(report_, "diverged_frames"));
}

// Once a second of frames (the last second partial), the strongest press over that second: the
// run's strongest is one of them.
TEST_F(ShortSoak, PerSecondSamplesCoverTheRunAndHoldItsStrongestPress) {
  const std::size_t samples = report_.find("\"per_second\":");
  ASSERT_NE(samples, std::string::npos);
  const std::regex force("\"max_contact_force_n\": ([-0-9.eE+]+)");
  int count = 0;
  double strongest = 0.0;
  for (auto it = std::sregex_iterator(report_.begin() + static_cast<std::ptrdiff_t>(samples),
                                      report_.end(), force);
       it != std::sregex_iterator(); ++it) {
    ++count;
    strongest = std::max(strongest, std::stod((*it)[1]));
  }
  const double frames = json_number(report_, "frames");
  const double frames_per_second = std::floor(1e6 / kFrameBudgetUs);
  EXPECT_EQ(count, static_cast<int>(std::ceil(frames / frames_per_second)));
  EXPECT_GT(strongest, 0.0);
  EXPECT_EQ(strongest, json_number(report_, "max_contact_force_n"));
}

// The samples say where the late frames came from: their late frames add up to the run's
// deadline misses with the rendering at its reserve, and the slowest of their slowest frames is
// the run's, with a method named and its tasks' times adding up to no more than the frame.
TEST_F(ShortSoak, PerSecondSamplesAccountForEveryLateFrame) {
  const std::size_t samples = report_.find("\"per_second\":");
  ASSERT_NE(samples, std::string::npos);
  const std::regex sample(
      "\"late_frames\": ([0-9]+), \"slowest_frame_us\": ([0-9]+), "
      "\"slowest_frame_simulation_us\": ([0-9]+), \"slowest_frame_method\": \"([a-z-]+)\", "
      "\"slowest_frame_bscan_us\": ([0-9]+), \"slowest_frame_view_us\": ([0-9]+), "
      "\"slowest_frame_render_us\": ([0-9]+)");
  // The rendering's reserve: its task's budget, as the run had it.
  const std::size_t render = report_.find("\"render\": {\"runs\":");
  ASSERT_NE(render, std::string::npos);
  const double render_reserve_us = json_number(report_, "budget_us", render);
  double late = 0.0;
  double slowest_us = 0.0;
  int count = 0;
  for (auto it = std::sregex_iterator(report_.begin() + static_cast<std::ptrdiff_t>(samples),
                                      report_.end(), sample);
       it != std::sregex_iterator(); ++it) {
    ++count;
    late += std::stod((*it)[1]);
    const double frame_us = std::stod((*it)[2]);
    slowest_us = std::max(slowest_us, frame_us);
    // Its tasks ran one after another within it; the rendering at most at its reserve.
    const double tasks_us =
        std::stod((*it)[3]) + std::stod((*it)[5]) + std::stod((*it)[6]) + std::stod((*it)[7]);
    EXPECT_LE(tasks_us, frame_us) << "sample " << count;
    EXPECT_GT(std::stod((*it)[7]), 0.0) << "every frame renders; sample " << count;
    EXPECT_LE(std::stod((*it)[7]), render_reserve_us) << "sample " << count;
  }
  const double frames_per_second = std::floor(1e6 / kFrameBudgetUs);
  EXPECT_EQ(count, static_cast<int>(std::ceil(json_number(report_, "frames") / frames_per_second)));
  const std::size_t capped = report_.find("\"frame_time_render_capped\":");
  ASSERT_NE(capped, std::string::npos);
  EXPECT_EQ(late, json_number(report_, "deadline_misses", capped));
  EXPECT_EQ(slowest_us, json_number(report_, "max_us", capped));
}

TEST_F(ShortSoak, MemoryGrowthStaysWithinTheExactFemCacheBound) {
  const double growth_kib = json_number(report_, "growth_kib");
  EXPECT_LE(growth_kib, 200.0 * 1024) << "resident memory grew " << growth_kib / 1024 << " MB";
}

// What the program holds allocated falls as a case switch frees the old case's engines (the soak's
// second case is smaller); resident memory falls with it only if the freed memory is handed back.
// Kept by the allocator, resident memory less the heap in use grew 99 MB over this run (a
// 30-minute soak's medians per tenth: 139 → 291 MB); handed back, 4.4 MB.
TEST_F(ShortSoak, FreedMemoryIsHandedBackAtCaseSwitches) {
  const std::size_t memory = report_.find("\"memory\":");
  ASSERT_NE(memory, std::string::npos);
  const double heap_growth_kib = json_number(report_, "heap_in_use_growth_kib", memory);
  EXPECT_LE(heap_growth_kib, 200.0 * 1024) << "the heap in use grew " << heap_growth_kib / 1024;
  const double beyond_kib = json_number(report_, "resident_beyond_heap_growth_kib", memory);
  EXPECT_LE(beyond_kib, 32.0 * 1024)
      << "resident memory beyond the heap in use grew " << beyond_kib / 1024 << " MB";
}

TEST_F(ShortSoak, DeadlineMissesStayWithinTheStatedBound) {
  const double frames = json_number(report_, "frames");
  const std::size_t capped = report_.find("\"frame_time_render_capped\":");
  ASSERT_NE(capped, std::string::npos);
  const double misses = json_number(report_, "deadline_misses", capped);
  EXPECT_LE(misses, 0.6 * frames) << misses << " of " << frames
                                  << " frames over budget with the rendering at its reserve";
  const std::size_t by_method = report_.find("\"frame_time_by_method_render_capped\":");
  ASSERT_NE(by_method, std::string::npos);
  const std::size_t explicit_msds = report_.find("\"msds-explicit\": {", by_method);
  if (explicit_msds != std::string::npos) {
    EXPECT_LE(json_number(report_, "p50_us", explicit_msds), kFrameBudgetUs);
  }
}

}  // namespace
