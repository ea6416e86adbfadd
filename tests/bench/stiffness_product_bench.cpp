// The PCG FEM's product y = K x in the node-block form its CG uses (detail::NodeBlockMatrix: the
// upper triangle's 3 × 3 blocks) against Eigen's compressed-row product of the same K, one
// thread, in the same iterations (alternating, so both see the same machine): a stitched
// sub-volume of 15³ nodes and the 52 × 52 × 12 one-piece mesh of table 5.1. Counters: each
// form's mean µs per product and blocks / eigen.
// BM_CorotationalProduct: the corotational FEM's product (its warped K in full block rows, every
// block stored twice, tangent_stiffness_times) against the same K in the node-block form, on
// `copies` 15³-node sub-volumes in turn (1: each product's K still in cache from the last; 10:
// 36 MB of full rows, as a frame with ten sub-volumes in the probe's reach). Counters: each
// form's µs for all the copies' products, blocks / rows.
//   build/ci/tests/bench/stiffness_product_bench

#include <benchmark/benchmark.h>

#include <chrono>
#include <memory>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/node_block_matrix.hpp"

namespace {

using namespace ultrasim;
using Clock = std::chrono::steady_clock;

// A soft muscle block on a 2 mm grid, its bottom layer fixed.
struct GridBlock {
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed;
};

GridBlock grid_block(const Eigen::Vector3i& nodes) {
  GridBlock b;
  b.mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
      Eigen::Vector3d::Zero(), 2.0 * (nodes - Eigen::Vector3i::Ones()).cast<double>(), nodes));
  b.materials.assign(b.mesh.tet_count(), sim::Material{1, "muscle", 30.0, 0.45});
  b.fixed.assign(b.mesh.node_count(), 0);
  for (int n = 0; n < nodes.x() * nodes.y(); ++n) b.fixed[n] = 1;
  return b;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness(const Eigen::Vector3i& nodes) {
  const GridBlock b = grid_block(nodes);
  return sim::LinearFem(b.mesh, b.materials, b.fixed, sim::FemSettings{}).stiffness();
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

void BM_CorotationalProduct(benchmark::State& state) {
  const GridBlock b = grid_block({15, 15, 15});
  const int copies = static_cast<int>(state.range(0));
  std::vector<std::unique_ptr<sim::CorotationalFem>> fems;
  std::vector<sim::detail::NodeBlockMatrix> node_blocks;
  for (int c = 0; c < copies; ++c) {
    fems.push_back(std::make_unique<sim::CorotationalFem>(b.mesh, b.materials, b.fixed,
                                                          sim::CorotationalSettings{}, nullptr));
    fems.back()->step(nullptr, 1.0 / 60);  // its warped K at rest: the linear FEM's
    node_blocks.emplace_back(fems.back()->warped_stiffness(), 1);
  }
  std::vector<Eigen::VectorXd> spills(1);
  Eigen::VectorXd x = Eigen::VectorXd::Random(3 * b.mesh.node_count());
  Eigen::VectorXd y_rows(x.size()), y_blocks(x.size());
  double rows_s = 0.0, blocks_s = 0.0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    for (auto& fem : fems) fem->tangent_stiffness_times(x, y_rows);
    const auto t1 = Clock::now();
    for (auto& blocks : node_blocks) {
      blocks.times_band(0, x, nullptr, y_blocks, spills[0]);
      blocks.add_spills(spills, y_blocks);
    }
    const auto t2 = Clock::now();
    benchmark::DoNotOptimize(y_rows.data());
    benchmark::DoNotOptimize(y_blocks.data());
    rows_s += std::chrono::duration<double>(t1 - t0).count();
    blocks_s += std::chrono::duration<double>(t2 - t1).count();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["rows_us"] = 1e6 * rows_s / n;
  state.counters["blocks_us"] = 1e6 * blocks_s / n;
  state.counters["blocks/rows"] = blocks_s / rows_s;
  state.counters["max_difference"] =
      (y_blocks - y_rows).cwiseAbs().maxCoeff() / y_rows.cwiseAbs().maxCoeff();
}
BENCHMARK(BM_CorotationalProduct)
    ->Arg(1)
    ->Arg(4)
    ->Arg(10)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

BENCHMARK(BM_StiffnessProduct)
    ->ArgName("mesh")
    ->Arg(0)
    ->Arg(1)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
