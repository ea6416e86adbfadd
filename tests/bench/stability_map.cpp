// Where each deformation method fails, as a CSV for the stability chart (docs/accuracy.md):
//   build/ci/tests/bench/stability_map --out DIR
//   /usr/bin/python3 scripts/plot_engines.py --stability DIR --out docs/images
// writes DIR/stability-dt.csv, stability-nu.csv and stability-depth.csv.
//
// Three sweeps on the engine benchmarks' block (fat over muscle, fixed at the bottom, 45 mm
// deep) at 16 × 8 × 8 nodes, each row one (method, parameters) run with what the engine reported:
//   dt:    the MSDS integrators with physical masses, time step × stiffness (every modulus
//          scaled), a linear face pressing 2 mm; beside the explicit bound from the largest
//          stiffness-to-mass ratio (MsdsEngine::explicit_stable_time_step_s).
//   nu:    every method at Poisson's ratio 0.3 → 0.499, pressed 4 mm and held; the error against
//          the exact FEM at the same ν after the press and after the hold.
//   depth: every method pushed 0 → 60 mm into the 45 mm block, 0.5 mm a frame; per depth the
//          inverted tets, whether the frame diverged and what the engine did about it.
// A study, not a benchmark: nothing is timed, and nothing here asserts (the tests do:
// msds_test, locking_test, corotational_fem_test and the engines' ProbeDeeperThanTheTissue
// tests). Takes about 3 minutes on 2 cores.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "engine_scene.hpp"
#include "engine_settings.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/msds.hpp"

namespace {

using namespace ultrasim;

constexpr int kNodes[3] = {16, 8, 8};
constexpr double kFrameDtS = 1.0 / 60.0;

// The block with every modulus scaled and every Poisson's ratio set.
std::vector<sim::Material> materials(double modulus_scale, double poisson_ratio) {
  std::vector<sim::Material> m = bench::block(kNodes[0], kNodes[1], kNodes[2]).materials;
  for (auto& material : m) {
    material.youngs_modulus_kpa *= modulus_scale;
    material.poisson_ratio = poisson_ratio;
  }
  return m;
}

sim::ProbeCollider face_at_depth(double depth_mm) {
  return sim::ProbeCollider::linear_face(Eigen::Vector3d(0.0, 0.3, depth_mm),
                                         Eigen::Quaterniond::Identity(), 38.0, 10.0, 2.0);
}

std::unique_ptr<sim::DeformationEngine> make(sim::EngineKind kind,
                                             const std::vector<sim::Material>& m,
                                             const sim::EngineSettings& settings) {
  const bench::Block& b = bench::block(kNodes[0], kNodes[1], kNodes[2]);
  return sim::make_engine(kind, b.mesh, m, b.fixed, settings, b.skin);
}

double relative_error(const Eigen::VectorXd& got, const Eigen::VectorXd& want) {
  if (!got.allFinite()) return INFINITY;
  return bench::relative_max_error(got, want);
}

int tet_count() {
  return bench::block(kNodes[0], kNodes[1], kNodes[2]).mesh.tet_count();
}

// dt × stiffness for both MSDS integrators, physical masses: 10 frames of 20 steps while a face
// presses 2 mm (0.2 mm a frame).
void sweep_time_step(std::ofstream& csv) {
  const double scales[] = {0.1, 0.3, 1.0, 3.0, 10.0};
  for (double scale : scales) {
    const auto m = materials(scale, 0.45);
    for (int e = -16; e <= -4; ++e) {  // dt = 10^(e/2) s: 1e-8 .. 1e-2
      const double dt_s = std::pow(10.0, 0.5 * e);
      for (auto kind : {sim::EngineKind::kMsdsExplicit, sim::EngineKind::kMsdsImplicit}) {
        // The map is drawn for the published stick contact (docs/accuracy.md's figures).
        sim::EngineSettings settings = testing::stick_contact();
        settings.msds.scale_mass_for_explicit_step = false;
        settings.msds.time_step_s = dt_s;
        settings.msds.steps_per_frame = 20;
        settings.msds.implicit_steps_per_frame = 20;
        const auto engine = make(kind, m, settings);
        double bound_s = 0.0;
        if (const auto* msds = dynamic_cast<const sim::MsdsEngine*>(engine.get())) {
          bound_s = msds->explicit_stable_time_step_s();
        }
        bool diverged = false;
        sim::Recovery recovery = sim::Recovery::kNone;
        for (int frame = 1; frame <= 10; ++frame) {
          const auto probe = face_at_depth(0.2 * frame);
          const auto s = engine->step(&probe, kFrameDtS);
          diverged |= s.diverged;
          recovery = sim::worse_recovery(recovery, s.recovery);
        }
        csv << sim::engine_key(kind) << ',' << dt_s << ',' << scale * 20.0 << ',' << scale * 50.0
            << ',' << bound_s << ',' << diverged << ',' << sim::recovery_key(recovery) << '\n';
      }
    }
    std::printf("dt sweep: moduli x%g done\n", scale);
  }
}

// ν for every method: a 4 mm press over 20 frames, then 40 frames held; error against the exact
// FEM (stick contact, the rule the others follow) at the same ν.
void sweep_poisson_ratio(std::ofstream& csv) {
  const double nus[] = {0.3, 0.4, 0.45, 0.48, 0.49, 0.495, 0.499};
  const sim::EngineKind kinds[] = {sim::EngineKind::kPcgFem, sim::EngineKind::kCorotationalFem,
                                   sim::EngineKind::kMsdsExplicit, sim::EngineKind::kMsdsImplicit,
                                   sim::EngineKind::kExactFem};
  for (double nu : nus) {
    const auto m = materials(1.0, nu);
    sim::EngineSettings settings = testing::stick_contact();
    settings.exact.contact = sim::ContactModel::kStick;
    const auto reference = make(sim::EngineKind::kExactFem, m, settings);
    std::vector<std::unique_ptr<sim::DeformationEngine>> engines;
    for (auto kind : kinds) engines.push_back(make(kind, m, settings));
    std::vector<double> error_pressed(engines.size());
    std::vector<sim::EngineStepStats> last(engines.size());
    std::vector<int> diverged(engines.size(), 0);
    std::vector<sim::Recovery> recovery(engines.size(), sim::Recovery::kNone);
    for (int frame = 1; frame <= 60; ++frame) {
      const auto probe = face_at_depth(std::min(4.0, 0.2 * frame));
      reference->step(&probe, kFrameDtS);
      for (std::size_t i = 0; i < engines.size(); ++i) {
        last[i] = engines[i]->step(&probe, kFrameDtS);
        diverged[i] |= last[i].diverged;
        recovery[i] = sim::worse_recovery(recovery[i], last[i].recovery);
        if (frame == 20) {
          error_pressed[i] =
              relative_error(engines[i]->displacements_mm(), reference->displacements_mm());
        }
      }
    }
    for (std::size_t i = 0; i < engines.size(); ++i) {
      const double error_held =
          relative_error(engines[i]->displacements_mm(), reference->displacements_mm());
      csv << sim::engine_key(kinds[i]) << ',' << nu << ',' << error_pressed[i] << ',' << error_held
          << ',' << diverged[i] << ',' << sim::recovery_key(recovery[i]) << ','
          << last[i].relative_residual << ',' << last[i].contact_force_n << '\n';
    }
    std::printf("nu sweep: %g done\n", nu);
  }
}

// Every method pushed through the 45 mm block, 0.5 mm a frame to 60 mm.
void sweep_depth(std::ofstream& csv) {
  const sim::EngineKind kinds[] = {
      sim::EngineKind::kPcgFem,       sim::EngineKind::kMsdsExplicit,
      sim::EngineKind::kExactFem,     sim::EngineKind::kCorotationalFem,
      sim::EngineKind::kMsdsImplicit, sim::EngineKind::kHyperelasticFem};
  const auto m = materials(1.0, 0.45);
  for (auto kind : kinds) {
    const auto engine = make(kind, m, testing::stick_contact());
    for (int frame = 1; frame <= 120; ++frame) {
      const double depth_mm = 0.5 * frame;
      const auto probe = face_at_depth(depth_mm);
      const auto s = engine->step(&probe, kFrameDtS);
      const bool finite = engine->displacements_mm().allFinite();
      csv << sim::engine_key(kind) << ',' << depth_mm << ','
          << static_cast<double>(s.inverted_tets) / tet_count() << ',' << s.diverged << ','
          << sim::recovery_key(s.recovery) << ',' << finite << ',' << s.contact_force_n << '\n';
    }
    std::printf("depth sweep: %s done\n", std::string(sim::engine_key(kind)).c_str());
  }
}

}  // namespace

// Opens DIR/name with its header line, or exits with a clear message.
std::ofstream open_csv(const std::string& dir, const char* name, const char* header) {
  const std::string path = dir + "/" + name;
  std::ofstream csv(path);
  if (!csv) {
    std::fprintf(stderr, "stability_map: cannot write %s\n", path.c_str());
    std::exit(1);
  }
  csv << header << '\n';
  return csv;
}

int main(int argc, char** argv) {
  // The folder is asked for: a default of "." once left truncated CSVs at the repository's root.
  std::string out;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
      out = argv[++i];
      continue;
    }
    std::fprintf(stderr, "stability_map: unknown argument %s\n", argv[i]);
    out.clear();
    break;
  }
  if (out.empty()) {
    std::fprintf(stderr, "usage: stability_map --out DIR\n");
    return 2;
  }
  // diverged: the engine detected a divergence (NaN, energy growth, inversion) in some frame;
  // recovery: the worst it did about one (none, substepped, kept-last-good, reset).
  auto dt = open_csv(out, "stability-dt.csv",
                     "method,dt_s,fat_kpa,muscle_kpa,explicit_bound_dt_s,diverged,recovery");
  auto nu = open_csv(out, "stability-nu.csv",
                     "method,nu,error_after_press,error_after_hold,diverged,recovery,"
                     "last_relative_residual,contact_force_n");
  auto depth = open_csv(out, "stability-depth.csv",
                        "method,depth_mm,inverted_fraction,diverged,recovery,finite,"
                        "contact_force_n");
  sweep_time_step(dt);
  sweep_poisson_ratio(nu);
  sweep_depth(depth);
  std::printf("wrote %s/stability-{dt,nu,depth}.csv\n", out.c_str());
  return 0;
}
