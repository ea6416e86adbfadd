#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/volume.hpp"
#include "ultrasim/kiosk/display_surfaces.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

// A case that cannot be turned into tissue (what() names the file and the cause).
class CaseError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A case loaded and meshed, ready to simulate: immutable after loading, shared by the session.
struct TissueCase {
  config::CaseSettings settings;
  imaging::Volume<std::uint8_t> volume;      // B-mode echo
  imaging::Volume<std::uint8_t> labels;      // tissue labels (docs/case-format.md)
  geometry::GridSpec grid;                   // the tet grid over the case's region
  geometry::TetMesh mesh;                    // make_grid_tet_mesh(grid): the rest configuration
  std::vector<sim::Material> tet_materials;  // one per tet ([mesh] material_mixing)
  std::vector<std::uint8_t> fixed_nodes;     // one per node: fixed faces and fixed labels
  // What the 3D view's wireframe draws: the mesh nodes on its surface (the view uploads only
  // these: a fifth of a large mesh's nodes), and levels of detail of lines between them, as
  // index pairs into view_nodes, finest first (the surface's tet edges, then the grid lines
  // through every 1st, 2nd, 4th, ... node: geometry::grid_surface_lines) with their spacing.
  std::vector<std::uint32_t> view_nodes;
  std::vector<std::vector<std::uint32_t>> line_levels;
  std::vector<float> line_level_spacing_mm;
  std::vector<DisplaySurface> structures;  // vein, artery, nerve, bone, as the 3D view shows them
};

// Loads case.toml and its volumes, lays the tet grid over the region and assigns materials and
// fixed nodes. Throws config::ConfigError, imaging::MetaImageError or CaseError, each naming the
// file. Allocates; start-up only.
TissueCase load_tissue_case(const std::filesystem::path& case_dir);

}  // namespace ultrasim::kiosk
