// The PCG FEM's product y = K x in the node-block form its CG uses (detail::NodeBlockMatrix: the
// upper triangle's 3 × 3 blocks) against Eigen's compressed-row product of the same K, one
// thread, in the same iterations (alternating, so both see the same machine): a stitched
// sub-volume of 15³ nodes and the 52 × 52 × 12 one-piece mesh of table 5.1. Counters: each
// form's mean µs per product and blocks / eigen.
//   build/ci/tests/bench/stiffness_product_bench

#include <benchmark/benchmark.h>

#include <chrono>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/node_block_matrix.hpp"

namespace {

using namespace ultrasim;
using Clock = std::chrono::steady_clock;

Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness(const Eigen::Vector3i& nodes) {
  const geometry::TetMesh mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
      Eigen::Vector3d::Zero(), 2.0 * (nodes - Eigen::Vector3i::Ones()).cast<double>(), nodes));
  std::vector<sim::Material> materials(mesh.tet_count(), sim::Material{1, "muscle", 30.0, 0.45});
  std::vector<std::uint8_t> fixed(mesh.node_count(), 0);
  for (int n = 0; n < nodes.x() * nodes.y(); ++n) fixed[n] = 1;
  return sim::LinearFem(mesh, materials, fixed, sim::FemSettings{}).stiffness();
}

void BM_StiffnessProduct(benchmark::State& state) {
  const Eigen::Vector3i nodes =
      state.range(0) == 0 ? Eigen::Vector3i(15, 15, 15) : Eigen::Vector3i(52, 52, 12);
  const Eigen::SparseMatrix<double, Eigen::RowMajor> k = stiffness(nodes);
  const sim::detail::NodeBlockMatrix blocks(k, 4);  // as the PCG FEM's on one or two threads
  std::vector<Eigen::VectorXd> spills(blocks.bands());
  Eigen::VectorXd x = Eigen::VectorXd::Random(k.rows());
  Eigen::VectorXd y_eigen(k.rows()), y_blocks(k.rows());
  double eigen_s = 0.0, blocks_s = 0.0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    y_eigen.noalias() = k * x;
    const auto t1 = Clock::now();
    for (int band = 0; band < blocks.bands(); ++band) {
      blocks.times_band(band, x, nullptr, y_blocks, spills[band]);
    }
    blocks.add_spills(spills, y_blocks);
    const auto t2 = Clock::now();
    benchmark::DoNotOptimize(y_eigen.data());
    benchmark::DoNotOptimize(y_blocks.data());
    eigen_s += std::chrono::duration<double>(t1 - t0).count();
    blocks_s += std::chrono::duration<double>(t2 - t1).count();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["eigen_us"] = 1e6 * eigen_s / n;
  state.counters["blocks_us"] = 1e6 * blocks_s / n;
  state.counters["blocks/eigen"] = blocks_s / eigen_s;
  state.counters["max_difference"] =
      (y_blocks - y_eigen).cwiseAbs().maxCoeff() / y_eigen.cwiseAbs().maxCoeff();
}

BENCHMARK(BM_StiffnessProduct)
    ->ArgName("mesh")
    ->Arg(0)
    ->Arg(1)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
