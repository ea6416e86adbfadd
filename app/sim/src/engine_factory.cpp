#include "ultrasim/sim/engine_factory.hpp"

#include <array>
#include <stdexcept>
#include <utility>

#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/exact_fem.hpp"
#include "ultrasim/sim/hyperelastic_fem.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {

namespace {

constexpr std::array<std::pair<EngineKind, std::string_view>, 6> kKeys = {{
    {EngineKind::kPcgFem, "pcg"},
    {EngineKind::kMsdsExplicit, "msds-explicit"},
    {EngineKind::kExactFem, "exact"},
    {EngineKind::kCorotationalFem, "corotational"},
    {EngineKind::kMsdsImplicit, "msds-implicit"},
    {EngineKind::kHyperelasticFem, "hyperelastic"},
}};

}  // namespace

std::unique_ptr<DeformationEngine> make_engine(EngineKind kind, const geometry::TetMesh& mesh,
                                               std::span<const Material> tet_materials,
                                               std::span<const std::uint8_t> fixed_nodes,
                                               const EngineSettings& settings,
                                               std::span<const std::uint8_t> skin_nodes,
                                               hal::JobSystem* jobs) {
  switch (kind) {
    case EngineKind::kPcgFem:
      return std::make_unique<LinearFem>(mesh, tet_materials, fixed_nodes, settings.fem, jobs);
    case EngineKind::kMsdsExplicit:
      return std::make_unique<MsdsEngine>(MsdsIntegrator::kExplicitEuler, mesh, tet_materials,
                                          fixed_nodes, settings.msds, jobs, skin_nodes);
    case EngineKind::kExactFem:
      return std::make_unique<ExactFem>(mesh, tet_materials, fixed_nodes, settings.exact,
                                        skin_nodes, jobs);
    case EngineKind::kCorotationalFem:
      return std::make_unique<CorotationalFem>(mesh, tet_materials, fixed_nodes,
                                               settings.corotational, jobs);
    case EngineKind::kMsdsImplicit:
      return std::make_unique<MsdsEngine>(MsdsIntegrator::kImplicitEuler, mesh, tet_materials,
                                          fixed_nodes, settings.msds, jobs, skin_nodes);
    case EngineKind::kHyperelasticFem:
      return std::make_unique<HyperelasticFem>(mesh, tet_materials, fixed_nodes,
                                               settings.hyperelastic, jobs);
  }
  throw std::invalid_argument("make_engine: unknown method");
}

std::string_view engine_key(EngineKind kind) {
  for (const auto& [k, key] : kKeys) {
    if (k == kind) return key;
  }
  return "unknown";
}

std::optional<EngineKind> engine_from_key(std::string_view key) {
  for (const auto& [k, name] : kKeys) {
    if (name == key) return k;
  }
  return std::nullopt;
}

}  // namespace ultrasim::sim
