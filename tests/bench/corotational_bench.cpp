// The corotational FEM's frame with kept rotations (rotation_update_tolerance: 1e-3 and the
// default 1e-2) against its reference, every tet's rotation extracted and its blocks summed every
// frame (0), both stepped through the same frames, alternating, so that both see the same machine.
// Scene: the engine benchmarks' block (the default case's region, 60 × 40 × 45 mm) at the default
// case's mesh (37 × 9 × 28 nodes), two threads as in the kiosk; probe: the 38 mm face pressed 4 mm,
// then
// (`slide` 1) sliding ±5 mm at 0.5 mm a frame or (`slide` 0) held; the kept run's tets within
// the tolerance checked every frame or every other (`check_interval`). Counters: each one's mean ms
// a frame, kept/every, the share of rotations the kept run extracted a frame, and its field's
// difference from the reference's after the measured frames (max norm, relative).
// BM_CarriedTissueProduct: a stitched sub-volume's step (15³ nodes, its update every other step,
// turns checked every other update, `iterations` CG iterations a step: 1 in the frames whose share
// is spent) whose CG start reads K u carried over from the last solve (tissue_product_refresh_steps
// 16, the default), against the reference that computes it every solve (1); the same press and
// slide, alternating. Counters: each one's mean ms a step, carried/fresh, and their fields'
// difference after the measured steps (max norm, relative).
// BM_TermSwaps: the same sub-volume's step whose update swaps its moved tets' terms in K_R's
// blocks (term_swap_max_fraction 0.25, the default) against the reference that sums the blocks of
// the rows they hold again (0); counters as BM_CarriedTissueProduct's.
// BM_InvertedTetRotation: a tet's rotation from an inverted deformation gradient (a deep press's
// lost tets, taken again at every update), polar_rotation's fast path against the SVD it
// replaced, on the same 4,096 gradients; counters: ns a tet each, and SVD / fast.
// BM_TurnCheck: the update's turn check, the AVX2 kernel against the portable one (below).
//   build/ci/tests/bench/corotational_bench

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "../../app/sim/src/polar_rotation.hpp"
#include "../../app/sim/src/rotation_turns.hpp"
#include "engine_scene.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/corotational_fem.hpp"

namespace {

using namespace ultrasim;
using Clock = std::chrono::steady_clock;

void BM_KeptRotations(benchmark::State& state) {
  const double tolerance = 1e-3 * static_cast<double>(state.range(0));
  const bool slide = state.range(1) != 0;
  const double cap = 1e-2 * static_cast<double>(state.range(2));
  const int check_interval = static_cast<int>(state.range(3));
  const bench::Block& b = bench::block(37, 9, 28);
  drivers::posix::ThreadPool jobs(2);
  sim::CorotationalSettings every_settings, kept_settings;
  every_settings.rotation_update_tolerance = 0.0;
  every_settings.max_rotation_updates_fraction = 1.0;
  kept_settings.rotation_update_tolerance = tolerance;
  kept_settings.max_rotation_updates_fraction = cap;
  kept_settings.turn_check_interval_frames = check_interval;
  sim::CorotationalFem every(b.mesh, b.materials, b.fixed, every_settings, &jobs);
  sim::CorotationalFem kept(b.mesh, b.materials, b.fixed, kept_settings, &jobs);
  const auto probe_at = [&](int frame) {
    return bench::probe_at(slide ? frame : std::min(frame, 20));
  };
  int frame = 0;
  for (; frame < bench::kAccuracyFrames; ++frame) {  // the press (and a slide), untimed
    const auto probe = probe_at(frame);
    every.step(&probe, bench::kFrameDtS);
    kept.step(&probe, bench::kFrameDtS);
  }
  double every_s = 0.0, kept_s = 0.0, rotations = 0.0;
  for (auto _ : state) {
    const auto probe = probe_at(frame++);
    const auto t0 = Clock::now();
    every.step(&probe, bench::kFrameDtS);
    const auto t1 = Clock::now();
    kept.step(&probe, bench::kFrameDtS);
    const auto t2 = Clock::now();
    every_s += std::chrono::duration<double>(t1 - t0).count();
    kept_s += std::chrono::duration<double>(t2 - t1).count();
    rotations += kept.rotations_updated();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["every_ms"] = 1e3 * every_s / n;
  state.counters["kept_ms"] = 1e3 * kept_s / n;
  state.counters["kept/every"] = kept_s / every_s;
  state.counters["rotations_share"] = rotations / (n * kept.tet_count());
  state.counters["difference"] =
      bench::relative_max_error(kept.displacements_mm(), every.displacements_mm());
}

BENCHMARK(BM_KeptRotations)
    ->ArgNames({"tolerance_e-3", "slide", "cap_percent", "check_interval"})
    ->Args({1, 1, 100, 1})
    ->Args({10, 1, 100, 1})
    ->Args({10, 1, 5, 1})
    ->Args({10, 1, 2, 1})
    ->Args({10, 1, 2, 2})
    ->Args({1, 0, 100, 1})
    ->Args({10, 0, 100, 1})
    ->Args({10, 0, 5, 1})
    ->Args({10, 0, 2, 1})
    ->Args({10, 0, 2, 2})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

// A stitched sub-volume as the stitched volume steps it: its update every other step, turns
// checked every other update, the benchmark's argument CG iterations a step.
sim::CorotationalSettings sub_volume_settings(const benchmark::State& state) {
  sim::CorotationalSettings s;
  s.pcg_iterations_per_frame = static_cast<int>(state.range(0));
  s.rotation_update_interval_frames = 2;
  s.turn_check_interval_frames = 2;
  return s;
}

// A 15³ sub-volume with `reference_settings` and one with `candidate_settings`, stepped through
// the press and slide, untimed, then through the measured frames, alternating; sets the counters
// `<names>_ms` (mean a step), the ratio and their fields' difference after the measured steps
// (max norm, relative).
void alternate(benchmark::State& state, const sim::CorotationalSettings& reference_settings,
               const sim::CorotationalSettings& candidate_settings,
               const std::string& reference_name, const std::string& candidate_name) {
  const bench::Block& b = bench::block(15, 15, 15);
  sim::CorotationalFem reference(b.mesh, b.materials, b.fixed, reference_settings);
  sim::CorotationalFem candidate(b.mesh, b.materials, b.fixed, candidate_settings);
  int frame = 0;
  for (; frame < bench::kAccuracyFrames; ++frame) {
    const auto probe = bench::probe_at(frame);
    reference.step(&probe, bench::kFrameDtS);
    candidate.step(&probe, bench::kFrameDtS);
  }
  double reference_s = 0.0, candidate_s = 0.0;
  for (auto _ : state) {
    const auto probe = bench::probe_at(frame++);
    const auto t0 = Clock::now();
    reference.step(&probe, bench::kFrameDtS);
    const auto t1 = Clock::now();
    candidate.step(&probe, bench::kFrameDtS);
    const auto t2 = Clock::now();
    reference_s += std::chrono::duration<double>(t1 - t0).count();
    candidate_s += std::chrono::duration<double>(t2 - t1).count();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters[reference_name + "_ms"] = 1e3 * reference_s / n;
  state.counters[candidate_name + "_ms"] = 1e3 * candidate_s / n;
  state.counters[candidate_name + "/" + reference_name] = candidate_s / reference_s;
  state.counters["difference"] =
      bench::relative_max_error(candidate.displacements_mm(), reference.displacements_mm());
}

// One and five CG iterations a step.
void sub_volume_pair_runs(benchmark::internal::Benchmark* b) {
  b->ArgName("iterations")
      ->Arg(1)
      ->Arg(5)
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond)
      ->MinTime(2.0);
}

void BM_CarriedTissueProduct(benchmark::State& state) {
  sim::CorotationalSettings fresh = sub_volume_settings(state), carried = fresh;
  fresh.tissue_product_refresh_steps = 1;
  carried.tissue_product_refresh_steps = 16;
  alternate(state, fresh, carried, "fresh", "carried");
}
BENCHMARK(BM_CarriedTissueProduct)->Apply(sub_volume_pair_runs);

void BM_TermSwaps(benchmark::State& state) {
  sim::CorotationalSettings summed = sub_volume_settings(state), swapped = summed;
  summed.term_swap_max_fraction = 0.0;
  swapped.term_swap_max_fraction = 0.25;
  alternate(state, summed, swapped, "summed", "swapped");
}
BENCHMARK(BM_TermSwaps)->Apply(sub_volume_pair_runs);

void BM_InvertedTetRotation(benchmark::State& state) {
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> stretch(0.2, 1.5);
  const auto rotation = [&] {
    return Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
        .normalized()
        .toRotationMatrix();
  };
  std::vector<Eigen::Matrix3d> gradients(4096);
  for (auto& f : gradients) {
    const Eigen::Vector3d s(stretch(rng), stretch(rng), -stretch(rng));
    f = rotation() * s.asDiagonal() * rotation().transpose();
  }
  double fast_s = 0.0, svd_s = 0.0, sink = 0.0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    for (const auto& f : gradients) sink += sim::corotational_detail::polar_rotation(f)(0, 0);
    const auto t1 = Clock::now();
    for (const auto& f : gradients) sink += sim::corotational_detail::rotation_by_svd(f)(0, 0);
    const auto t2 = Clock::now();
    fast_s += std::chrono::duration<double>(t1 - t0).count();
    svd_s += std::chrono::duration<double>(t2 - t1).count();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
  }
  benchmark::DoNotOptimize(sink);
  const double tets = static_cast<double>(state.iterations()) * 4096.0;
  state.counters["fast_ns"] = 1e9 * fast_s / tets;
  state.counters["svd_ns"] = 1e9 * svd_s / tets;
  state.counters["svd/fast"] = svd_s / fast_s;
}

BENCHMARK(BM_InvertedTetRotation)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

// BM_TurnCheck: the update's turn check over a stitched sub-volume's 13,720 tets (15³ nodes,
// 1.8 mm apart as in the large case), pressed 3 mm and turned 0.2 rad, each tet holding its
// rotation of a little before: the fastest kernel (AVX2 here) against the portable one and the
// check as written with Eigen before the kernels (reference_turn), every tet in order,
// alternating. Counters: ns a tet each, and portable / fastest, Eigen / fastest.
void BM_TurnCheck(benchmark::State& state) {
  namespace detail = sim::corotational_detail;
  const geometry::TetMesh mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(25.2), Eigen::Vector3i::Constant(15)));
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 0.2, 1.0).normalized()).toRotationMatrix();
  Eigen::VectorXd u(3 * mesh.node_count());
  for (int n = 0; n < mesh.node_count(); ++n) {
    const Eigen::Vector3d& p = mesh.rest_positions_mm[n];
    const double dent = 3.0 * std::exp(-(p - Eigen::Vector3d(12.6, 12.6, 0)).squaredNorm() / 80.0);
    u.segment<3>(3 * n) = turn * (p + Eigen::Vector3d(0, 0, dent)) - p;
  }
  std::vector<Eigen::Matrix<double, 3, 4>> gradients;
  std::vector<Eigen::Matrix3d> rotations;
  const Eigen::Matrix3d behind =
      Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (const geometry::Tet& tet : mesh.tets) {
    Eigen::Matrix3d edges, deformed;
    for (int b = 1; b < 4; ++b) {
      edges.col(b - 1) = mesh.rest_positions_mm[tet[b]] - mesh.rest_positions_mm[tet[0]];
      deformed.col(b - 1) = edges.col(b - 1) + u.segment<3>(3 * tet[b]) - u.segment<3>(3 * tet[0]);
    }
    Eigen::Matrix<double, 3, 4> g;
    g.rightCols<3>() = edges.inverse().transpose();
    g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
    gradients.push_back(g);
    rotations.push_back(detail::polar_rotation(deformed * edges.inverse()) * behind);
  }
  const detail::TurnInputs inputs{mesh.tets.data(), mesh.rest_positions_mm.data(), u.data(),
                                  gradients.data(), rotations.data()};
  std::vector<int> every(mesh.tets.size());
  for (std::size_t t = 0; t < every.size(); ++t) every[t] = static_cast<int>(t);
  std::vector<double> turns(mesh.tets.size());
  // The check as the engine wrote it before the kernels: Eigen's F, then reference_turn.
  const auto eigen_turns = [&] {
    for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
      const geometry::Tet& tet = mesh.tets[t];
      const auto x = [&](int a) -> Eigen::Vector3d {
        return mesh.rest_positions_mm[tet[a]] + u.segment<3>(3 * tet[a]);
      };
      Eigen::Matrix3d e;
      e.col(0) = x(1) - x(0);
      e.col(1) = x(2) - x(0);
      e.col(2) = x(3) - x(0);
      turns[t] = detail::reference_turn(rotations[t],
                                        e.lazyProduct(gradients[t].rightCols<3>().transpose()));
    }
  };
  double fastest_s = 0.0, portable_s = 0.0, eigen_s = 0.0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    detail::fastest_turn_kernel()(inputs, every, turns.data());
    const auto t1 = Clock::now();
    detail::portable_turn_kernel()(inputs, every, turns.data());
    const auto t2 = Clock::now();
    eigen_turns();
    const auto t3 = Clock::now();
    benchmark::DoNotOptimize(turns.data());
    fastest_s += std::chrono::duration<double>(t1 - t0).count();
    portable_s += std::chrono::duration<double>(t2 - t1).count();
    eigen_s += std::chrono::duration<double>(t3 - t2).count();
    state.SetIterationTime(std::chrono::duration<double>(t3 - t0).count());
  }
  const double tets = static_cast<double>(state.iterations()) * static_cast<double>(every.size());
  state.counters["fastest_ns"] = 1e9 * fastest_s / tets;
  state.counters["portable_ns"] = 1e9 * portable_s / tets;
  state.counters["eigen_ns"] = 1e9 * eigen_s / tets;
  state.counters["portable/fastest"] = portable_s / fastest_s;
  state.counters["eigen/fastest"] = eigen_s / fastest_s;
}

BENCHMARK(BM_TurnCheck)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
