// The cost of the Coulomb slip (slide_held_node, the default) against the published stick
// contact, in the same run: a 12 × 6 mm face pressed 2 mm into a 70 × 70 × 22 mm slab (2 mm
// tets, fat over muscle) and sliding ±3 mm, one piece, one thread, per method that holds its
// contacts (PCG FEM, explicit and implicit MSDS). The slip adds, per held node and step, one node's
// spring forces (MSDS) or one stiffness row (PCG FEM), a 3 × 3 block and a closest-point query.
// And find_contacts against asking every node (testing::naive_find_contacts) on a stitched
// sub-volume's 15³ nodes at 2 mm, the kiosk's 38 × 10 mm linear face pressed 2 mm into its
// middle, or at its corner (most nodes out of reach), tilted 6°.
//   build/ci/tests/bench/contact_bench

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "frame_time_reporter.hpp"
#include "naive_contacts.hpp"
#include "stitch_scene.hpp"
#include "ultrasim/sim/engine_factory.hpp"

namespace {

using namespace ultrasim;

constexpr sim::EngineKind kMethods[] = {sim::EngineKind::kPcgFem, sim::EngineKind::kMsdsExplicit,
                                        sim::EngineKind::kMsdsImplicit};
constexpr int kPressFrames = 20;

const bench::Region& slab() {
  static const bench::Region r = bench::make_region(36, 12);
  return r;
}

sim::ProbeCollider face_at(double x_mm, double depth_mm) {
  return sim::ProbeCollider::linear_face(
      Eigen::Vector3d(x_mm, 35.0, depth_mm),
      Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitZ())), 12.0,
      6.0, 2.0);
}

void BM_Contact(benchmark::State& state) {
  const auto method = kMethods[state.range(0)];
  sim::EngineSettings settings;
  settings.fem.contact.model = settings.msds.contact.model =
      state.range(1) != 0 ? sim::HeldContactModel::kCoulombSlip : sim::HeldContactModel::kStick;
  const bench::Region& r = slab();
  auto engine = sim::make_engine(method, r.mesh, r.materials, r.fixed, settings);
  for (int f = 0; f < kPressFrames; ++f) {
    const auto face = face_at(35.0, 2.0 * (f + 1.0) / kPressFrames);
    engine->step(&face, 1.0 / 60);
  }
  int frame = 0;
  int held = 0;
  double iterations = 0.0;  // CG iterations (the PCG FEM) or steps' (the MSDS), summed
  for (auto _ : state) {
    const auto face = face_at(35.0 + 3.0 * std::sin(0.05 * frame++), 2.0);
    const sim::EngineStepStats s = engine->step(&face, 1.0 / 60);
    held = s.contact_nodes;
    iterations += s.iterations;
  }
  state.counters["held"] = held;
  state.counters["iterations"] = iterations / frame;
}
BENCHMARK(BM_Contact)
    ->ArgsProduct({{0, 1, 2}, {0, 1}})
    ->ArgNames({"method", "slip"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(60)
    ->Repetitions(3);

void BM_FindContacts(benchmark::State& state) {
  constexpr int kSide = 15;
  constexpr double kSpacingMm = 2.0;
  std::vector<Eigen::Vector3d> nodes;
  for (int k = 0; k < kSide; ++k) {
    for (int j = 0; j < kSide; ++j) {
      for (int i = 0; i < kSide; ++i) nodes.emplace_back(kSpacingMm * Eigen::Vector3d(i, j, k));
    }
  }
  std::vector<std::uint8_t> fixed(nodes.size(), 0);
  const double at_mm = state.range(1) == 0 ? 14.0 : 0.0;  // the middle, or the corner
  const auto face = sim::ProbeCollider::linear_face(
      Eigen::Vector3d(at_mm, at_mm, 2.0),
      Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX())), 38.0, 10.0, 1.0);
  std::vector<sim::NodeContact> contacts;
  contacts.reserve(nodes.size());
  for (auto _ : state) {
    if (state.range(0) == 0) {
      testing::naive_find_contacts(face, nodes, fixed, 1e-6, contacts);
    } else {
      sim::find_contacts(face, nodes, fixed, 1e-6, contacts);
    }
    benchmark::DoNotOptimize(contacts.data());
  }
  state.counters["contacts"] = static_cast<double>(contacts.size());
}
BENCHMARK(BM_FindContacts)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->ArgNames({"fast", "corner"})
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(3);

class RatioReporter : public bench::FrameTimeReporter {
 public:
  void print_summary() const {
    std::printf("\nms per frame, stick (published) and Coulomb slip (default), same run\n");
    std::printf("%-14s %8s %8s %7s\n", "method", "stick", "slip", "ratio");
    for (int m = 0; m < 3; ++m) {
      const std::string name = "BM_Contact/method:" + std::to_string(m) + "/slip:";
      const double stick = median_ms_by_prefix(name + "0");
      const double slip = median_ms_by_prefix(name + "1");
      if (stick > 0.0 && slip > 0.0) {
        std::printf("%-14s %8.2f %8.2f %7.3f\n", std::string(sim::engine_key(kMethods[m])).c_str(),
                    stick, slip, slip / stick);
      }
    }
    std::printf(
        "\nfind_contacts on 15^3 nodes, us: every node asked (reference), box pre-reject\n");
    for (int corner = 0; corner < 2; ++corner) {
      const std::string tail = "/corner:" + std::to_string(corner);
      const double naive = 1e3 * median_ms_by_prefix("BM_FindContacts/fast:0" + tail);
      const double fast = 1e3 * median_ms_by_prefix("BM_FindContacts/fast:1" + tail);
      if (naive > 0.0 && fast > 0.0) {
        std::printf("%-14s %8.1f %8.1f %7.3f\n", corner != 0 ? "at the corner" : "in the middle",
                    naive, fast, fast / naive);
      }
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.print_summary();
  benchmark::Shutdown();
  return 0;
}
