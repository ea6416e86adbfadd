// DeformationEngine::step_within: what each method leaves for later when the frame's budget runs
// out, that it says so, that it never shows garbage, and that the CG methods make the skipped
// iterations up over the next frames (the exact FEM carries its contact rounds over, and its
// unheld nodes wait for the background); with time to spare it is exactly step().

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "block_fixture.hpp"
#include "engine_settings.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace ultrasim::sim {
namespace {

using testing::Block;

Block make_block() {
  return testing::make_block({11, 7, 6}, [](const Eigen::Vector3d& centroid) {
    return centroid.z() < 8.0 ? Material{1, "fat", 20.0, 0.45} : Material{2, "muscle", 60.0, 0.4};
  });
}

std::vector<std::uint8_t> skin_where(const Block& b, bool (*keep)(const Eigen::Vector3d&)) {
  std::vector<std::uint8_t> skin(b.mesh.node_count(), 0);
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    const Eigen::Vector3d& p = b.mesh.rest_positions_mm[n];
    skin[n] = p.z() == 0.0 && keep(p);
  }
  return skin;
}

// A linear probe's face `depth_mm` below the skin at x = y = 0, beam straight down.
ProbeCollider pressed(double depth_mm) {
  return ProbeCollider::linear_face(Eigen::Vector3d(0.0, 0.3, depth_mm),
                                    Eigen::Quaterniond::Identity(), 24.0, 8.0, 2.0);
}

std::unique_ptr<DeformationEngine> make(EngineKind kind, const Block& b,
                                        const std::vector<std::uint8_t>& skin,
                                        const EngineSettings& settings = {}) {
  return make_engine(kind, b.mesh, b.materials, b.fixed, settings, skin);
}

// Without friction a still probe has one answer, whatever path the frames took to it (with
// friction, any state whose held nodes' pull stays inside the friction cone is at rest).
EngineSettings frictionless() {
  return ultrasim::testing::with_held_contact(HeldContactModel::kCoulombSlip, 0.0);
}

double max_abs(const Eigen::VectorXd& v) {
  return v.lpNorm<Eigen::Infinity>();
}

const auto kAllSkin = [](const Eigen::Vector3d&) { return true; };

// Green's functions precomputed for the skin at x < 0 only: a probe at x = 0 also presses nodes
// whose columns would each take a solve with the factor.
std::vector<std::uint8_t> half_skin(const Block& b) {
  return skin_where(b, [](const Eigen::Vector3d& p) { return p.x() < 0.0; });
}

// The exact FEM (half the skin precomputed) under `probe` with no budget, stepped until its
// active set stops moving.
std::unique_ptr<ExactFem> settled_exact_fem(const Block& b, const ProbeCollider& probe) {
  auto unlimited =
      std::make_unique<ExactFem>(b.mesh, b.materials, b.fixed, ExactFemSettings{}, half_skin(b));
  for (int frame = 0; frame < 30; ++frame) unlimited->step(&probe, 1.0 / 60);
  return unlimited;
}

// Budgets for the tests: never more time, and one that counts how often it was asked.
const StepBudget kNoTime = [] { return false; };

TEST(StepBudget, WithTimeToSpareEveryMethodIsExactlyStep) {
  const Block b = make_block();
  const auto skin = skin_where(b, kAllSkin);
  const ProbeCollider probe = pressed(2.0);
  for (EngineKind kind : {EngineKind::kPcgFem, EngineKind::kCorotationalFem, EngineKind::kExactFem,
                          EngineKind::kMsdsExplicit, EngineKind::kMsdsImplicit}) {
    SCOPED_TRACE(engine_key(kind));
    auto stepped = make(kind, b, skin);
    auto budgeted = make(kind, b, skin);
    int asked = 0;
    const StepBudget plenty = [&asked] { return ++asked > 0; };
    for (int frame = 0; frame < 3; ++frame) {
      const EngineStepStats a = stepped->step(&probe, 1.0 / 60);
      const EngineStepStats c = budgeted->step_within(&probe, 1.0 / 60, plenty);
      EXPECT_EQ(a.iterations, c.iterations);
      EXPECT_FALSE(c.cut_short);
    }
    EXPECT_EQ(stepped->displacements_mm(), budgeted->displacements_mm());
    EXPECT_GT(asked, 0);
  }
}

TEST(StepBudget, ConjugateGradientMethodsRunOneIterationWithoutTimeAndCatchUpOverFrames) {
  const Block b = make_block();
  const auto skin = skin_where(b, kAllSkin);
  const ProbeCollider probe = pressed(2.0);
  for (EngineKind kind : {EngineKind::kPcgFem, EngineKind::kCorotationalFem}) {
    SCOPED_TRACE(engine_key(kind));
    auto full = make(kind, b, skin, frictionless());
    auto starved = make(kind, b, skin, frictionless());
    for (int frame = 0; frame < 60; ++frame) full->step(&probe, 1.0 / 60);
    const Eigen::VectorXd& want = full->displacements_mm();

    const EngineStepStats first = starved->step_within(&probe, 1.0 / 60, kNoTime);
    EXPECT_EQ(first.iterations, 1);
    EXPECT_TRUE(first.cut_short);
    EXPECT_FALSE(first.diverged);
    EXPECT_TRUE(starved->displacements_mm().allFinite());
    const double first_error = max_abs(starved->displacements_mm() - want);
    // One warm-started iteration a frame: the same answer, later.
    for (int frame = 1; frame < 600; ++frame) starved->step_within(&probe, 1.0 / 60, kNoTime);
    const double late_error = max_abs(starved->displacements_mm() - want);
    EXPECT_LT(late_error, 0.02 * max_abs(want)) << "first frame's error " << first_error;
    EXPECT_LT(late_error, 0.1 * first_error);
  }
}

TEST(StepBudget, PcgStopsWhereTheBudgetSays) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  auto fem = make(EngineKind::kPcgFem, b, {});
  int left = 4;
  const EngineStepStats s = fem->step_within(&probe, 1.0 / 60, [&left] { return left-- > 0; });
  EXPECT_EQ(s.iterations, 5);  // the first, then one for each "yes"
  EXPECT_TRUE(s.cut_short);
}

TEST(StepBudget, ExplicitMsdsStopsSteppingWhereTheBudgetSaysAfterItsFirstCheck) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  auto msds = make(EngineKind::kMsdsExplicit, b, {});
  int left = 3;
  const EngineStepStats s = msds->step_within(&probe, 1.0 / 60, [&left] { return left-- > 0; });
  // Four steps before the first question (the first inverted-tet check), then one for each "yes".
  EXPECT_EQ(s.iterations, 4 + 3);
  EXPECT_TRUE(s.cut_short);
  EXPECT_FALSE(s.diverged);
  EXPECT_TRUE(msds->displacements_mm().allFinite());
}

TEST(StepBudget, ExplicitMsdsWithoutTimeLagsAndSettlesWhereTheFullFramesDo) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  auto full = make(EngineKind::kMsdsExplicit, b, {});
  auto starved = make(EngineKind::kMsdsExplicit, b, {});
  full->step(&probe, 1.0 / 60);
  const Eigen::VectorXd first_frame = full->displacements_mm();
  for (int frame = 1; frame < 300; ++frame) full->step(&probe, 1.0 / 60);
  const Eigen::VectorXd want = full->displacements_mm();
  // Four steps of the 20 a frame: the same motion, five times as many frames.
  for (int frame = 0; frame < 1500; ++frame) {
    const EngineStepStats s = starved->step_within(&probe, 1.0 / 60, kNoTime);
    ASSERT_EQ(s.iterations, 4) << "frame " << frame;
    ASSERT_TRUE(s.cut_short);
    ASSERT_FALSE(s.diverged) << "frame " << frame;
    ASSERT_TRUE(starved->displacements_mm().allFinite());
    const double from_first_frame = max_abs(starved->displacements_mm() - first_frame);
    if (frame == 0) {
      EXPECT_GT(from_first_frame, 0.1 * max_abs(first_frame)) << "a fifth of the way";
    } else if (frame == 4) {
      EXPECT_LT(from_first_frame, 1e-3 * max_abs(first_frame)) << "one full frame's steps";
    }
  }
  EXPECT_LT(max_abs(starved->displacements_mm() - want), 0.02 * max_abs(want));
}

TEST(StepBudget, ImplicitMsdsWithoutTimeStaysFiniteAndSettlesNearTheFullSolve) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  auto full = make(EngineKind::kMsdsImplicit, b, {});
  auto starved = make(EngineKind::kMsdsImplicit, b, {});
  bool any_cut = false;
  for (int frame = 0; frame < 300; ++frame) {
    full->step(&probe, 1.0 / 60);
    const EngineStepStats s = starved->step_within(&probe, 1.0 / 60, kNoTime);
    any_cut = any_cut || s.cut_short;
    ASSERT_FALSE(s.diverged) << "frame " << frame;
    ASSERT_TRUE(starved->displacements_mm().allFinite());
  }
  EXPECT_TRUE(any_cut);
  const Eigen::VectorXd& want = full->displacements_mm();
  EXPECT_LT(max_abs(starved->displacements_mm() - want), 0.05 * max_abs(want));
}

// A step the budget stopped leaves its velocity unfinished; the next step's CG goes on from it
// (where that lowers the step's energy) instead of from zero. One iteration a step, a 1 mm press
// on a 21 × 11 × 11 block, the largest displacement's error after 10 / 20 / 60 frames under the
// still probe: from zero 16 / 13 / 6.0 %, going on 14 / 11 / 1.2 %. The smooth part of the press
// is what restarted iterations hardly reach (engine_budget_bench's ImplicitMsdsShare, the default
// case's grid under the kiosk's 4 ms share: 0.71-0.74 → 0.21-0.23 of the field while the probe
// slides).
TEST(StepBudget, ImplicitMsdsGoesOnFromWhereItsStoppedStepGot) {
  const Block b = testing::make_block({21, 11, 11}, [](const Eigen::Vector3d& centroid) {
    return centroid.z() < 8.0 ? Material{1, "fat", 20.0, 0.45} : Material{2, "muscle", 60.0, 0.4};
  });
  const ProbeCollider probe = pressed(1.0);
  auto full = make(EngineKind::kMsdsImplicit, b, {}, frictionless());
  auto starved = make(EngineKind::kMsdsImplicit, b, {}, frictionless());
  for (int frame = 0; frame < 100; ++frame) full->step(&probe, 1.0 / 60);
  const Eigen::VectorXd& want = full->displacements_mm();
  for (int frame = 0; frame < 60; ++frame) {
    const EngineStepStats s = starved->step_within(&probe, 1.0 / 60, kNoTime);
    ASSERT_FALSE(s.diverged) << "frame " << frame;
  }
  EXPECT_LT(max_abs(starved->displacements_mm() - want), 0.02 * max_abs(want));
}

TEST(StepBudget, MsdsRetriesARejectedFrameWithSmallerStepsOnlyWhileThereIsTime) {
  const Block b = make_block();
  for (EngineKind kind : {EngineKind::kMsdsExplicit, EngineKind::kMsdsImplicit}) {
    SCOPED_TRACE(engine_key(kind));
    // Put down deep at once, the face folds tets under its rim and the frame is rejected: find
    // a depth where this method's step(), smaller steps and all, refuses it.
    double depth_mm = 8.0;
    for (; depth_mm < 19.5; depth_mm += 1.0) {
      const ProbeCollider deep = pressed(depth_mm);
      if (make(kind, b, {})->step(&deep, 1.0 / 60).recovery == Recovery::kKeptLastGood) break;
    }
    ASSERT_LT(depth_mm, 19.5) << "no press was refused: the test would mean nothing";
    const ProbeCollider deep = pressed(depth_mm);
    int asked = 0;
    auto starved = make(kind, b, {});
    const EngineStepStats given_up =
        starved->step_within(&deep, 1.0 / 60, [&asked] { return ++asked < 0; });
    EXPECT_TRUE(given_up.diverged);
    EXPECT_TRUE(given_up.cut_short);
    EXPECT_EQ(given_up.recovery, Recovery::kKeptLastGood);
    EXPECT_EQ(max_abs(starved->displacements_mm()), 0.0) << "the frame's start: rest";
    EXPECT_GE(asked, 1) << "asked before the first retry";
  }
}

TEST(StepBudget, ExactFemHoldsNoNodeWithoutGreensFunctionsAndComputesNoneUnderABudget) {
  const Block b = make_block();
  const auto skin = half_skin(b);
  const ProbeCollider probe = pressed(2.0);
  ExactFem unlimited(b.mesh, b.materials, b.fixed, {}, skin);
  ExactFem budgeted(b.mesh, b.materials, b.fixed, {}, skin);

  const long long precomputed = budgeted.total_columns_computed();  // at construction
  const EngineStepStats deferred = budgeted.step_within(&probe, 1.0 / 60, kNoTime);
  EXPECT_TRUE(deferred.cut_short);
  EXPECT_EQ(budgeted.total_columns_computed(), precomputed);
  EXPECT_GT(deferred.contact_nodes, 0) << "the precomputed half still holds the probe";
  EXPECT_TRUE(budgeted.displacements_mm().allFinite());
  const EngineStepStats full = unlimited.step(&probe, 1.0 / 60);
  EXPECT_GT(unlimited.total_columns_computed(), precomputed);
  EXPECT_GT(full.contact_nodes, deferred.contact_nodes);

  // Once an unbudgeted frame has cached them, a budgeted frame holds them too: the same answer
  // as an unbudgeted frame from the same shape.
  ExactFem cached(b.mesh, b.materials, b.fixed, {}, skin);
  cached.step(&probe, 1.0 / 60);
  const long long computed = cached.total_columns_computed();
  const EngineStepStats again = cached.step_within(&probe, 1.0 / 60, kNoTime);
  unlimited.step(&probe, 1.0 / 60);
  EXPECT_FALSE(again.cut_short);
  EXPECT_EQ(cached.total_columns_computed(), computed);
  EXPECT_EQ(again.contact_nodes, unlimited.last_solve_stats().contact_nodes);
  EXPECT_EQ(cached.displacements_mm(), unlimited.displacements_mm());
}

// Without time, the exact FEM runs one contact round a frame (more only after a round that let
// nodes go) and the next frame carries on from where it stopped: its set settles a few frames
// later, and from there both go on the same way (each frame re-projects the nodes on the probe's
// curved rim from where they are, so a held probe's rim contact creeps to its equilibrium over
// frames). A probe lifted off lets the skin go on its first frame.
TEST(StepBudget, ExactFemCarriesItsContactRoundsOverFramesWithoutTime) {
  const Block b = make_block();
  // Every node's Green's functions precomputed: a press this deep holds nodes below the skin,
  // which a budgeted frame would otherwise leave to the background.
  const std::vector<std::uint8_t> every_node(b.mesh.node_count(), 1);
  const ProbeCollider probe = pressed(5.0);
  ExactFem unlimited(b.mesh, b.materials, b.fixed, {}, every_node);
  ExactFem starved(b.mesh, b.materials, b.fixed, {}, every_node);
  const EngineStepStats full = unlimited.step(&probe, 1.0 / 60);
  ASSERT_GE(full.iterations, 3) << "a press that takes rounds";
  const Eigen::VectorXd held_first_frame = unlimited.displacements_mm();
  const EngineStepStats first = starved.step_within(&probe, 1.0 / 60, kNoTime);
  EXPECT_TRUE(first.cut_short);
  EXPECT_LT(first.iterations, full.iterations);
  const double first_error = max_abs(starved.displacements_mm() - unlimited.displacements_mm());
  EXPECT_GT(first_error, 0.01);

  constexpr int kFrames = 60;
  int settled_on = 0;
  for (int frame = 1; frame < kFrames; ++frame) {
    const EngineStepStats a = unlimited.step(&probe, 1.0 / 60);
    const EngineStepStats c = starved.step_within(&probe, 1.0 / 60, kNoTime);
    EXPECT_EQ(a.iterations, 1) << "frame " << frame << ": carried over, settled in one round";
    if (settled_on == 0 && !c.cut_short) settled_on = frame + 1;
  }
  EXPECT_GT(settled_on, 0);
  EXPECT_LE(settled_on, 5);
  EXPECT_EQ(starved.last_solve_stats().contact_nodes, unlimited.last_solve_stats().contact_nodes);
  EXPECT_LT(max_abs(starved.displacements_mm() - unlimited.displacements_mm()), 1e-9);
  std::printf(
      "without time: set settled on frame %d (%d rounds unbudgeted), first frame %.3f mm off; "
      "under the held probe the rim contacts crept %.3f mm from its first frame\n",
      settled_on, full.iterations, first_error,
      max_abs(unlimited.displacements_mm() - held_first_frame));

  const ProbeCollider lifted = pressed(-5.0);
  const EngineStepStats off = starved.step_within(&lifted, 1.0 / 60, kNoTime);
  EXPECT_EQ(off.contact_nodes, 0);
  EXPECT_FALSE(off.cut_short);
  EXPECT_LT(max_abs(starved.displacements_mm()), 1e-9) << "at rest, not pulled up";
}

// A job system whose background thread is the test: post_background() keeps the task until
// run_background() runs it, so the frames and the background interleave as the test says.
class ManualBackground final : public hal::JobSystem {
 public:
  int thread_count() const override { return 1; }
  void run(int task_count, void (*task)(void*, int), void* context) override {
    for (int i = 0; i < task_count; ++i) task(context, i);
  }
  bool post_background(void (*task)(void*), void* context) override {
    if (task_ != nullptr) return false;
    task_ = task;
    context_ = context;
    return true;
  }
  bool run_background() {
    if (task_ == nullptr) return false;
    auto* task = task_;
    task_ = nullptr;
    task(context_);
    return true;
  }

 private:
  void (*task_)(void*) = nullptr;
  void* context_ = nullptr;
};

// Under a budget on every frame, the nodes a press defers get their Green's functions from the
// background one at a time, and the frames converge to the unbudgeted answer; no frame solves.
TEST(StepBudget, ExactFemGetsTheGreensFunctionsItDeferredFromTheBackground) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  ManualBackground jobs;
  ExactFem budgeted(b.mesh, b.materials, b.fixed, {}, half_skin(b), &jobs);
  const long long precomputed = budgeted.total_columns_computed();
  int background_solves = 0;
  EngineStepStats last;
  for (int frame = 0; frame < 200; ++frame) {
    const long long before = budgeted.total_columns_computed();
    last = budgeted.step_within(&probe, 1.0 / 60, kNoTime);
    // A frame takes at most the one node the background finished: 3 columns, no solve.
    ASSERT_LE(budgeted.total_columns_computed() - before, 3) << "frame " << frame;
    if (!last.cut_short) break;
    ASSERT_TRUE(jobs.run_background()) << "a cut-short frame asks for a node, frame " << frame;
    ++background_solves;
  }
  EXPECT_FALSE(last.cut_short);
  EXPECT_FALSE(jobs.run_background()) << "nothing left to ask for";
  // The active set settles over a few more frames, as the unbudgeted one's did.
  for (int frame = 0; frame < 30; ++frame) {
    last = budgeted.step_within(&probe, 1.0 / 60, kNoTime);
    ASSERT_FALSE(last.cut_short);
  }
  EXPECT_GT(background_solves, 1);
  EXPECT_EQ(budgeted.total_columns_computed() - precomputed, 3 * background_solves);
  const auto unlimited = settled_exact_fem(b, probe);
  EXPECT_EQ(last.contact_nodes, unlimited->last_solve_stats().contact_nodes);
  EXPECT_LT(max_abs(budgeted.displacements_mm() - unlimited->displacements_mm()), 1e-9);
  std::printf("%d nodes solved in the background, one a frame\n", background_solves);
}

// The same with the kiosk's thread pool: its background thread solves while the test waits.
TEST(StepBudget, ExactFemConvergesWithThePoolsBackgroundThread) {
  const Block b = make_block();
  const ProbeCollider probe = pressed(2.0);
  drivers::posix::ThreadPool jobs(2);
  ExactFem budgeted(b.mesh, b.materials, b.fixed, {}, half_skin(b), &jobs);
  EngineStepStats last;
  for (int frame = 0; frame < 200; ++frame) {
    last = budgeted.step_within(&probe, 1.0 / 60, kNoTime);
    if (!last.cut_short) break;
    jobs.background().wait_idle();
  }
  EXPECT_FALSE(last.cut_short);
  for (int frame = 0; frame < 30; ++frame) budgeted.step_within(&probe, 1.0 / 60, kNoTime);
  EXPECT_LT(max_abs(budgeted.displacements_mm() - settled_exact_fem(b, probe)->displacements_mm()),
            1e-9);
}

}  // namespace
}  // namespace ultrasim::sim
