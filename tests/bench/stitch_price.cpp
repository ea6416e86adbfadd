// The price of stitching and of skipping sub-volumes, as CSVs for the chart (docs/accuracy.md):
//   build/ci/tests/bench/stitch_price --out DIR [--quick] [--variant NAME] [--path-only]
//                                    [--contact stick|slip]
//   /usr/bin/python3 scripts/plot_engines.py --stitching DIR --out docs/images
// writes DIR/stitch-frames.csv, DIR/stitch-stiffness.csv and DIR/stitch-path.csv.
//
// The region of table 5.1 (25 sub-volumes of 12³ nodes, one 52 × 52 × 12 grid, 2 mm spacing,
// fat over muscle, fixed at the bottom) under the published sphere probe, in two scenarios:
//   pressed: pressed 4 mm at the middle of a sub-volume over 20 frames, slid 8 mm across a seam
//            and back over 60, then held still for 120;
//   placed:  put down 4 mm deep at once where four sub-volumes meet, then held for 200.
// The same frames run on the one-piece mesh with the same method: what differs is stitching.
// The published contact holds a node where it first met the probe (it never slides), so a
// pressed probe freezes whatever the stitched run did differently on the way in; the placed one
// shows what stitching itself costs once converged.
//   frames:    per frame, for each scenario, method and variant (selective or all; the
//              overlap's stiffness split among its copies, or each copy at full stiffness as
//              published; seams exchanged once, twice or 4 times a frame; the springs alone,
//              without the seams' remembered loads), the displacement error
//              against one piece (max norm over the largest one-piece displacement), the largest
//              gap between copies of a shared node before the midpoint display, the strongest seam
//              pull and the sub-volumes stepped.
//   stiffness: the seam spring's stiffness per modulus from 1 to 200 mm, placed scenario after
//              its hold: the gap and the error.
//   path:      one piece against itself: the placed probe put down 0.01 mm to the side, or
//              lowered over 4 frames instead of at once, 10 and 199 frames after it stops. The
//              stick contact makes the answer depend on the way in; this is the floor under any
//              stitched-against-one-piece error (--path-only: this study alone, ~40 s).
// Under the published stick contact unless --contact slip asks for the default frictionless
// Coulomb slip (engine_settings.hpp says why the figures are stick's).
// A study, not a benchmark: nothing is timed and nothing here asserts (stitched_volume_test
// does). Takes a few minutes.

#include <Eigen/Core>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "stitch_scene.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace {

using namespace ultrasim;

constexpr double kFrameDtS = 1.0 / 60.0;
constexpr int kPressFrames = 20, kSlideFrames = 60, kHoldFrames = 120;
constexpr int kSide = 52, kDepth = 12;
constexpr int kPlacedFrames = 200;
constexpr int kQuickFrames = 60;  // --quick: the placed scenario's first frames only
// Where sub-volumes (2, 2), (3, 2), (2, 3) and (3, 3) overlap: grid nodes 30 and 31 on x and y.
constexpr double kCornerMm = 61.0;

using bench::max_norm;
using bench::Region;
// The PCG FEM's, the corotational FEM's and the MSDS's held contact for every engine here
// (main() sets it).
sim::EngineSettings g_contact = bench::stick_contact();
const sim::EngineSettings& held_contact() {
  return g_contact;
}

sim::ProbeCollider placed_probe() {
  return bench::sphere_probe(kCornerMm, kCornerMm, 4.0);
}

// Pressed at the middle of sub-volume (2, 2), then slid to x = +8 mm (across the seam at the
// next sub-volume's first node, 20 mm on) and back, then still.
sim::ProbeCollider probe_at(int frame) {
  const double middle = 0.5 * bench::kStitchSpacingMm * (kSide - 1);
  const double depth = std::min(4.0, 0.2 * frame);
  double x = 0.0;
  if (frame >= kPressFrames && frame < kPressFrames + kSlideFrames) {
    const int f = frame - kPressFrames;
    x = f < kSlideFrames / 2 ? 16.0 * f / kSlideFrames : 16.0 * (kSlideFrames - f) / kSlideFrames;
  }
  return bench::sphere_probe(middle + x, middle, depth);
}

struct Variant {
  const char* name;
  bool selective;
  bool split_overlap_stiffness;
  int exchanges_per_frame;
  bool coarse_correction;
  int fine_correction_iterations = 0;
  double seam_load_rate = sim::StitchingSettings{}.seam_load_rate;
};

constexpr Variant kVariants[] = {
    {"selective", true, true, 1, false},
    {"springs-alone", true, true, 1, false, 0, 0.0},  // no remembered seam loads, as published
    {"all", false, true, 1, false},
    {"published-overlap", true, false, 1, false},
    {"2-exchanges", true, true, 2, false},  // the PCG FEM's default since 2026-11-27
    {"4-exchanges", true, true, 4, false},
    {"coarse", true, true, 1, true},
    {"coarse-4-exchanges", true, true, 4, true},
    {"fine", true, true, 1, false, 20},
};

constexpr sim::EngineKind kMethods[] = {sim::EngineKind::kPcgFem, sim::EngineKind::kMsdsExplicit,
                                        sim::EngineKind::kMsdsImplicit};

void frames_study(const Region& r, hal::JobSystem& jobs, bool quick, const std::string& only,
                  std::ofstream& out) {
  out << "scenario,method,variant,frame,phase,error,gap_mm,seam_force_mn,stepped,fine_iterations\n";
  for (const bool placed : {false, true}) {
    if (quick && !placed) continue;
    const int total = quick    ? kQuickFrames
                      : placed ? kPlacedFrames
                               : kPressFrames + kSlideFrames + kHoldFrames;
    const auto probe_for = [&](int f) { return placed ? placed_probe() : probe_at(f); };
    const char* scenario = placed ? "placed" : "pressed";
    for (auto method : kMethods) {
      auto one_piece =
          sim::make_engine(method, r.mesh, r.materials, r.fixed, held_contact(), {}, &jobs);
      std::vector<Eigen::VectorXd> reference;
      for (int f = 0; f < total; ++f) {
        const auto probe = probe_for(f);
        one_piece->step(&probe, kFrameDtS);
        reference.push_back(one_piece->displacements_mm());
      }
      for (const Variant& v : kVariants) {
        if (!only.empty() && only != v.name) continue;
        sim::StitchingSettings stitching;
        stitching.sub_volumes = {5, 5, 1};
        stitching.selective = v.selective;
        stitching.split_overlap_stiffness = v.split_overlap_stiffness;
        stitching.exchanges_per_frame = v.exchanges_per_frame;
        stitching.explicit_msds_exchanges_per_frame = v.exchanges_per_frame;
        stitching.implicit_msds_exchanges_per_frame = v.exchanges_per_frame;
        stitching.coarse_correction = v.coarse_correction;
        stitching.fine_correction_iterations = v.fine_correction_iterations;
        stitching.seam_load_rate = v.seam_load_rate;
        sim::StitchedVolume stitched(r.grid, r.materials, r.fixed, method, held_contact(),
                                     stitching, &jobs);
        double error_at_10 = 0.0;
        for (int f = 0; f < total; ++f) {
          const auto probe = probe_for(f);
          stitched.step(&probe, kFrameDtS);
          const auto& s = stitched.last_stitch_stats();
          const double error =
              max_norm(stitched.displacements_mm() - reference[f]) / max_norm(reference[f]);
          if (f == 10) error_at_10 = error;
          const char* phase = placed                            ? "hold"
                              : f < kPressFrames                ? "press"
                              : f < kPressFrames + kSlideFrames ? "slide"
                                                                : "hold";
          out << scenario << ',' << sim::engine_key(method) << ',' << v.name << ',' << f << ','
              << phase << ',' << error << ',' << s.max_gap_mm << ',' << s.max_seam_force_mn << ','
              << s.sub_volumes_stepped << ',' << s.fine_iterations << '\n';
        }
        std::fprintf(
            stderr, "frames: %s %s %s: error %.4f 10 frames in, %.4f at the end\n", scenario,
            sim::engine_key(method).data(), v.name, error_at_10,
            max_norm(stitched.displacements_mm() - reference.back()) / max_norm(reference.back()));
      }
    }
  }
}

// How far one piece's own answer moves when the probe comes down another way: the floor below
// which a stitched run's error cannot be told from the contact's dependence on the path.
void path_study(const Region& r, hal::JobSystem& jobs, std::ofstream& out) {
  out << "method,path,frames_at_rest,error\n";
  struct Path {
    const char* name;
    double offset_mm;
    int lowering_frames;
  };
  constexpr Path kPaths[] = {{"offset-0.01mm", 0.01, 1}, {"lowered-over-4-frames", 0.0, 4}};
  for (auto method : kMethods) {
    auto reference =
        sim::make_engine(method, r.mesh, r.materials, r.fixed, held_contact(), {}, &jobs);
    std::vector<Eigen::VectorXd> placed;
    for (int f = 0; f < kPlacedFrames; ++f) {
      const auto probe = placed_probe();
      reference->step(&probe, kFrameDtS);
      placed.push_back(reference->displacements_mm());
    }
    for (const Path& p : kPaths) {
      auto other =
          sim::make_engine(method, r.mesh, r.materials, r.fixed, held_contact(), {}, &jobs);
      for (int f = 0; f < kPlacedFrames + p.lowering_frames - 1; ++f) {
        const double depth = 4.0 * std::min(1.0, (f + 1.0) / p.lowering_frames);
        const auto probe = bench::sphere_probe(kCornerMm + p.offset_mm, kCornerMm, depth);
        other->step(&probe, kFrameDtS);
        const int at_rest = f - (p.lowering_frames - 1);
        if (at_rest == 10 || at_rest == kPlacedFrames - 1) {
          const double error =
              max_norm(other->displacements_mm() - placed[at_rest]) / max_norm(placed[at_rest]);
          out << sim::engine_key(method) << ',' << p.name << ',' << at_rest << ',' << error << '\n';
          std::fprintf(stderr, "path: %s %s, %d frames at rest: %.4f\n",
                       sim::engine_key(method).data(), p.name, at_rest, error);
        }
      }
    }
  }
}

void stiffness_study(const Region& r, hal::JobSystem& jobs, std::ofstream& out) {
  out << "method,stiffness_per_modulus_mm,error,gap_mm\n";
  const auto probe = placed_probe();
  for (auto method : kMethods) {
    auto one_piece =
        sim::make_engine(method, r.mesh, r.materials, r.fixed, held_contact(), {}, &jobs);
    for (int f = 0; f < kPlacedFrames; ++f) one_piece->step(&probe, kFrameDtS);
    for (double k : {1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0}) {
      sim::StitchingSettings stitching;
      stitching.sub_volumes = {5, 5, 1};
      stitching.selective = false;
      stitching.spring_stiffness_per_modulus_mm = k;
      stitching.implicit_msds_spring_stiffness_per_modulus_mm = k;  // its own seams' setting
      stitching.exchanges_per_frame = 1;  // as charted (the default was 1 until 2026-11-27)
      sim::StitchedVolume stitched(r.grid, r.materials, r.fixed, method, held_contact(), stitching,
                                   &jobs);
      for (int f = 0; f < kPlacedFrames; ++f) stitched.step(&probe, kFrameDtS);
      const double error = max_norm(stitched.displacements_mm() - one_piece->displacements_mm()) /
                           max_norm(one_piece->displacements_mm());
      out << sim::engine_key(method) << ',' << k << ',' << error << ','
          << stitched.last_stitch_stats().max_gap_mm << '\n';
      std::fprintf(stderr, "stiffness: %s k %g error %.4f gap %.4f\n",
                   sim::engine_key(method).data(), k, error,
                   stitched.last_stitch_stats().max_gap_mm);
    }
  }
}

int usage(const char* problem, const char* argument) {
  std::fprintf(stderr, "stitch_price: %s%s\n", problem, argument);
  std::fprintf(stderr,
               "usage: stitch_price --out DIR [--quick] [--variant NAME] [--path-only] "
               "[--contact stick|slip]\nvariants:");
  for (const Variant& v : kVariants) std::fprintf(stderr, " %s", v.name);
  std::fprintf(stderr, "\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  std::string only;
  bool quick = false;
  bool path_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    const bool takes_value =
        argument == "--out" || argument == "--variant" || argument == "--contact";
    if (takes_value && i + 1 >= argc) return usage("a value is missing after ", argv[i]);
    if (argument == "--out") {
      dir = argv[++i];
    } else if (argument == "--variant") {
      only = argv[++i];
      if (std::none_of(std::begin(kVariants), std::end(kVariants),
                       [&](const Variant& v) { return only == v.name; })) {
        return usage("no variant named ", only.c_str());
      }
    } else if (argument == "--contact") {
      const std::string contact = argv[++i];
      if (contact == "slip") {
        g_contact = testing::with_held_contact(sim::HeldContactModel::kCoulombSlip, 0.0);
      } else if (contact != "stick") {
        return usage("--contact takes stick or slip, not ", contact.c_str());
      }
    } else if (argument == "--quick") {
      quick = true;
    } else if (argument == "--path-only") {
      path_only = true;
    } else {
      return usage("unknown argument ", argv[i]);
    }
  }
  if (dir.empty()) return usage("--out DIR is needed", "");
  const Region r = bench::make_region(kSide, kDepth);
  drivers::posix::ThreadPool jobs(2);
  std::ofstream frames(dir + "/stitch-frames.csv");
  std::ofstream stiffness(dir + "/stitch-stiffness.csv");
  if (!frames || !stiffness) {
    std::fprintf(stderr, "stitch_price: cannot write in %s\n", dir.c_str());
    return 1;
  }
  if (path_only) {
    std::ofstream path(dir + "/stitch-path.csv");
    path_study(r, jobs, path);
    return 0;
  }
  frames_study(r, jobs, quick, only, frames);
  if (!quick) {
    stiffness_study(r, jobs, stiffness);
    std::ofstream path(dir + "/stitch-path.csv");
    path_study(r, jobs, path);
  }
  return 0;
}
