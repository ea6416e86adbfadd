// Vessel surfaces of the default case (issue 4, item 5):
//  - building them: marching cubes on the label volume for vein, artery, nerve and bone, then
//    Taubin λ|μ smoothing (published: 5 surfaces, 243,224 triangles, built in 4 s; target ≤ 1 s);
//  - embedding them in the tet mesh (once per case load);
//  - moving them every frame from the deformed nodes, on 1 and 2 threads (target ≤ 2 ms).
//
//   build/<dir>/tests/bench/surface_bench --benchmark_repetitions=3
//       --benchmark_report_aggregates_only=true [--labels=path/to/labels.mha]   (one line)
//
// Without --labels it reads the default case the build generates beside this program
// (<build>/cases/default/labels.mha).

#include <benchmark/benchmark.h>

#include <atomic>
#include <barrier>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "ultrasim/geometry/marching_cubes.hpp"
#include "ultrasim/geometry/smoothing.hpp"
#include "ultrasim/geometry/surface_embedding.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/geometry/triangle_mesh.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace {

using namespace ultrasim;

std::filesystem::path g_labels_path;

struct Structure {
  const char* name;
  std::uint8_t label;
};
constexpr Structure kStructures[] = {{"vein", 4}, {"artery", 5}, {"nerve", 6}, {"bone", 7}};

const imaging::Volume<std::uint8_t>& labels() {
  static const imaging::Volume<std::uint8_t> volume = imaging::read_volume_u8(g_labels_path);
  return volume;
}

geometry::LabelGridView view_of(const imaging::Volume<std::uint8_t>& volume) {
  return {volume.size(), volume.spacing_mm(), volume.origin_mm(), volume.direction(),
          volume.voxels()};
}

// The four surfaces, smoothed, merged into one mesh (one embedding, one update per frame).
struct Surfaces {
  geometry::TriangleMesh merged;
  std::vector<int> triangles_per_structure;
};

geometry::TriangleMesh build_surface(const geometry::LabelGridView& grid, std::uint8_t label) {
  geometry::TriangleMesh mesh = geometry::marching_cubes(grid, geometry::LabelSet{label});
  geometry::taubin_smooth(mesh, geometry::TaubinSettings{});
  return mesh;
}

const Surfaces& surfaces() {
  static const Surfaces s = [] {
    Surfaces out;
    const geometry::LabelGridView grid = view_of(labels());
    for (const Structure& structure : kStructures) {
      const geometry::TriangleMesh mesh = build_surface(grid, structure.label);
      const auto offset = static_cast<std::int32_t>(out.merged.vertices_mm.size());
      out.merged.vertices_mm.insert(out.merged.vertices_mm.end(), mesh.vertices_mm.begin(),
                                    mesh.vertices_mm.end());
      for (auto t : mesh.triangles) {
        for (auto& v : t) v += offset;
        out.merged.triangles.push_back(t);
      }
      out.triangles_per_structure.push_back(mesh.triangle_count());
    }
    return out;
  }();
  return s;
}

// The whole build: marching cubes and 100 Taubin iterations for each structure.
void BM_BuildSurfaces(benchmark::State& state) {
  const geometry::LabelGridView grid = view_of(labels());
  std::vector<int> triangles(std::size(kStructures));
  for (auto _ : state) {
    for (std::size_t s = 0; s < std::size(kStructures); ++s) {
      const geometry::TriangleMesh mesh = build_surface(grid, kStructures[s].label);
      triangles[s] = mesh.triangle_count();
      benchmark::DoNotOptimize(mesh.vertices_mm.data());
    }
  }
  int total = 0;
  for (std::size_t s = 0; s < std::size(kStructures); ++s) {
    state.counters[std::string("tris_") + kStructures[s].name] = triangles[s];
    total += triangles[s];
  }
  state.counters["tris_total"] = total;
}
BENCHMARK(BM_BuildSurfaces)->Unit(benchmark::kMillisecond);

// The two halves of the build on their own, with what smoothing does to each structure's volume.
void BM_MarchingCubesOnly(benchmark::State& state) {
  const geometry::LabelGridView grid = view_of(labels());
  geometry::MarchingCubesStats stats;
  std::int64_t cubes = 0;
  for (auto _ : state) {
    cubes = 0;
    for (const Structure& structure : kStructures) {
      const geometry::TriangleMesh mesh =
          geometry::marching_cubes(grid, geometry::LabelSet{structure.label}, &stats);
      cubes += stats.cubes_visited;
      benchmark::DoNotOptimize(mesh.vertices_mm.data());
    }
  }
  state.counters["cubes_visited"] = static_cast<double>(cubes);
}
BENCHMARK(BM_MarchingCubesOnly)->Unit(benchmark::kMillisecond);

void BM_TaubinOnly(benchmark::State& state) {
  const geometry::LabelGridView grid = view_of(labels());
  std::vector<geometry::TriangleMesh> raw;
  for (const Structure& structure : kStructures) {
    raw.push_back(geometry::marching_cubes(grid, geometry::LabelSet{structure.label}));
  }
  std::vector<geometry::TriangleMesh> smoothed = raw;
  for (auto _ : state) {
    state.PauseTiming();
    smoothed = raw;
    state.ResumeTiming();
    for (auto& mesh : smoothed) geometry::taubin_smooth(mesh, geometry::TaubinSettings{});
  }
  for (std::size_t s = 0; s < raw.size(); ++s) {
    state.counters[std::string("vol_change_pct_") + kStructures[s].name] =
        100.0 *
        (geometry::enclosed_volume_mm3(smoothed[s]) / geometry::enclosed_volume_mm3(raw[s]) - 1.0);
  }
}
BENCHMARK(BM_TaubinOnly)->Unit(benchmark::kMillisecond);

// The simulated region of the default case (case.toml [mesh]) at a given node count, and a smooth
// press under a probe at the top centre, as the deformed node positions of one frame.
struct DeformedMesh {
  geometry::TetMesh mesh;
  std::vector<Eigen::Vector3d> deformed_mm;
};

DeformedMesh deformed_mesh(const Eigen::Vector3i& nodes) {
  DeformedMesh d{geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
                     Eigen::Vector3d(-30, -20, 0), Eigen::Vector3d(30, 20, 45), nodes)),
                 {}};
  d.deformed_mm = d.mesh.rest_positions_mm;
  for (auto& p : d.deformed_mm) {
    const double falloff = std::exp(-(p.x() * p.x() + p.y() * p.y()) / 200.0);
    p.z() += 8.0 * falloff * (1.0 - p.z() / 45.0);
  }
  return d;
}

const Eigen::Vector3i kMeshSizes[] = {{25, 9, 19}, {32, 16, 16}};

// Embedding cost, once per case load.
void BM_EmbedSurfaces(benchmark::State& state) {
  const DeformedMesh d = deformed_mesh(kMeshSizes[state.range(0)]);
  const Surfaces& s = surfaces();
  int outside = 0;
  for (auto _ : state) {
    const geometry::SurfaceEmbedding embedding(d.mesh, s.merged.vertices_mm);
    outside = embedding.outside_vertex_count();
    benchmark::DoNotOptimize(embedding.vertices().data());
  }
  state.counters["vertices"] = s.merged.vertex_count();
  state.counters["outside_vertices"] = outside;
  state.counters["tets"] = d.mesh.tet_count();
}
BENCHMARK(BM_EmbedSurfaces)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// A second thread that updates the upper half of the vertices whenever the frame thread updates
// the lower half: a persistent worker, as a job system would run it, so the figure holds the two
// barrier hand-offs of a frame but not thread creation.
class HalfWorker {
 public:
  HalfWorker(const geometry::SurfaceEmbedding& embedding, std::span<const Eigen::Vector3d> nodes,
             std::span<Eigen::Vector3d> out)
      : embedding_(embedding),
        nodes_(nodes),
        out_(out),
        split_(embedding.vertex_count() / 2),
        worker_([this] {
          for (;;) {
            start_.arrive_and_wait();
            if (quit_.load(std::memory_order_relaxed)) return;
            embedding_.update_range(split_, embedding_.vertex_count(), nodes_, out_);
            done_.arrive_and_wait();
          }
        }) {}
  ~HalfWorker() {
    quit_.store(true, std::memory_order_relaxed);
    start_.arrive_and_wait();
    worker_.join();
  }
  void frame() {
    start_.arrive_and_wait();
    embedding_.update_range(0, split_, nodes_, out_);
    done_.arrive_and_wait();
  }

 private:
  const geometry::SurfaceEmbedding& embedding_;
  std::span<const Eigen::Vector3d> nodes_;
  std::span<Eigen::Vector3d> out_;
  int split_;
  std::barrier<> start_{2};
  std::barrier<> done_{2};
  std::atomic<bool> quit_{false};
  std::thread worker_;  // last: starts after everything it reads is constructed
};

void BM_SurfaceUpdate(benchmark::State& state) {
  const DeformedMesh d = deformed_mesh(kMeshSizes[state.range(0)]);
  const int threads = static_cast<int>(state.range(1));
  const Surfaces& s = surfaces();
  const geometry::SurfaceEmbedding embedding(d.mesh, s.merged.vertices_mm);
  std::vector<Eigen::Vector3d> out(s.merged.vertices_mm.size());
  if (threads == 1) {
    for (auto _ : state) {
      embedding.update(d.deformed_mm, out);
      benchmark::ClobberMemory();
    }
  } else {
    HalfWorker worker(embedding, d.deformed_mm, out);
    for (auto _ : state) {
      worker.frame();
      benchmark::ClobberMemory();
    }
  }
  state.counters["vertices"] = embedding.vertex_count();
  state.counters["triangles"] = s.merged.triangle_count();
  state.counters["nodes"] = d.mesh.node_count();
}
BENCHMARK(BM_SurfaceUpdate)
    ->ArgNames({"mesh", "threads"})
    ->Args({0, 1})
    ->Args({0, 2})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  // Our own flag first, then Google Benchmark's.
  std::vector<char*> args;
  for (int a = 0; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg.rfind("--labels=", 0) == 0) {
      g_labels_path = arg.substr(9);
    } else {
      args.push_back(argv[a]);
    }
  }
  if (g_labels_path.empty()) {
    g_labels_path = std::filesystem::weakly_canonical(std::filesystem::path(argv[0]))
                        .parent_path()
                        .parent_path()
                        .parent_path() /
                    "cases" / "default" / "labels.mha";
  }
  if (!std::filesystem::exists(g_labels_path)) {
    std::fprintf(stderr,
                 "surface_bench: no label volume at %s (build ultrasim_default_case, or pass "
                 "--labels=PATH)\n",
                 g_labels_path.c_str());
    return 2;
  }
  int count = static_cast<int>(args.size());
  benchmark::Initialize(&count, args.data());
  if (benchmark::ReportUnrecognizedArguments(count, args.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
