#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string_view>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"
#include "ultrasim/sim/engine.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// Every method's settings, so any of them can be built on demand (a live switch).
struct EngineSettings {
  FemSettings fem;
  ExactFemSettings exact;
  MsdsSettings msds;
  CorotationalSettings corotational;
  HyperelasticSettings hyperelastic;
};

// Builds the given method on the mesh. `skin_nodes` (empty or one flag per node) are the nodes
// the probe can reach: the exact FEM precomputes their Green's functions, and the MSDS lets only
// these slide along the probe (empty: its mesh's boundary). `jobs`, if given, must
// outlive the engine. Throws std::invalid_argument for bad inputs (as the engines' constructors).
std::unique_ptr<DeformationEngine> make_engine(EngineKind kind, const geometry::TetMesh& mesh,
                                               std::span<const Material> tet_materials,
                                               std::span<const std::uint8_t> fixed_nodes,
                                               const EngineSettings& settings,
                                               std::span<const std::uint8_t> skin_nodes = {},
                                               hal::JobSystem* jobs = nullptr);

// The method's short name in config files, reports and the command line: "pcg", "msds-explicit",
// "exact", "corotational", "msds-implicit", "hyperelastic".
std::string_view engine_key(EngineKind kind);
std::optional<EngineKind> engine_from_key(std::string_view key);

}  // namespace ultrasim::sim
