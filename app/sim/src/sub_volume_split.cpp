#include "ultrasim/sim/sub_volume_split.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace ultrasim::sim {

namespace {

// First node of each of `count` boxes along an axis of `nodes` nodes, and one past the last node
// of the last box.
std::vector<int> axis_starts(int nodes, int count, int overlap_nodes, char axis) {
  // The cells not shared by neighbours: each box owns [b_i, b_{i+1}) of them plus the
  // overlap_nodes - 1 shared cells after.
  const int owned_cells = nodes - 1 - (overlap_nodes - 1);
  std::vector<int> starts(static_cast<std::size_t>(count) + 1);
  for (int i = 0; i <= count; ++i) {
    starts[i] = static_cast<int>(std::lround(static_cast<double>(i) * owned_cells / count));
  }
  for (int i = 0; i < count; ++i) {
    const int box_nodes = starts[i + 1] - starts[i] + overlap_nodes;
    if (count > 1 && box_nodes < overlap_nodes + 1) {
      throw std::invalid_argument(std::string("split_grid: ") + axis + " has " +
                                  std::to_string(nodes) + " nodes, too few for " +
                                  std::to_string(count) + " sub-volumes overlapping by " +
                                  std::to_string(overlap_nodes));
    }
  }
  return starts;
}

}  // namespace

std::vector<SubVolumeBox> split_grid(const Eigen::Vector3i& grid_nodes,
                                     const Eigen::Vector3i& sub_volumes, int overlap_nodes) {
  if ((sub_volumes.array() < 1).any()) {
    throw std::invalid_argument("split_grid: sub-volume counts must be >= 1");
  }
  if (overlap_nodes < 1) throw std::invalid_argument("split_grid: overlap_nodes must be >= 1");
  if ((grid_nodes.array() < 2).any()) {
    throw std::invalid_argument("split_grid: the grid needs >= 2 nodes per axis");
  }
  std::vector<int> starts[3];
  for (int a = 0; a < 3; ++a) {
    starts[a] = axis_starts(grid_nodes[a], sub_volumes[a], overlap_nodes, "xyz"[a]);
  }
  std::vector<SubVolumeBox> boxes;
  for (int k = 0; k < sub_volumes.z(); ++k) {
    for (int j = 0; j < sub_volumes.y(); ++j) {
      for (int i = 0; i < sub_volumes.x(); ++i) {
        SubVolumeBox box;
        box.index = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          const int s = box.index[a];
          box.first_node[a] = starts[a][s];
          // One box on an axis: the whole axis, not split.
          box.nodes[a] =
              sub_volumes[a] == 1 ? grid_nodes[a] : starts[a][s + 1] - starts[a][s] + overlap_nodes;
        }
        boxes.push_back(box);
      }
    }
  }
  return boxes;
}

geometry::TetMesh extract_sub_mesh(const geometry::GridSpec& grid,
                                   const geometry::TetMesh& grid_mesh, const SubVolumeBox& box,
                                   std::vector<int>* global_tets) {
  if (grid_mesh.tet_count() != 5 * (grid.nodes.array() - 1).prod()) {
    throw std::invalid_argument("extract_sub_mesh: the mesh is not make_grid_tet_mesh(grid)");
  }
  geometry::TetMesh mesh;
  mesh.rest_positions_mm.reserve(static_cast<std::size_t>(box.node_count()));
  for (int k = 0; k < box.nodes.z(); ++k) {
    for (int j = 0; j < box.nodes.y(); ++j) {
      for (int i = 0; i < box.nodes.x(); ++i) {
        const Eigen::Vector3i g = box.first_node + Eigen::Vector3i(i, j, k);
        mesh.rest_positions_mm.push_back(grid.node_position_mm(g.x(), g.y(), g.z()));
      }
    }
  }
  const Eigen::Vector3i grid_cells = grid.nodes.array() - 1;
  const Eigen::Vector3i box_cells = box.nodes.array() - 1;
  auto local_node = [&](int global_node) {
    const int gi = global_node % grid.nodes.x();
    const int gj = (global_node / grid.nodes.x()) % grid.nodes.y();
    const int gk = global_node / (grid.nodes.x() * grid.nodes.y());
    const Eigen::Vector3i l = Eigen::Vector3i(gi, gj, gk) - box.first_node;
    return l.x() + box.nodes.x() * (l.y() + box.nodes.y() * l.z());
  };
  // make_grid_tet_mesh emits five tets per cell, cells in x-fastest order.
  constexpr int kTetsPerCell = 5;
  if (global_tets != nullptr) global_tets->clear();
  for (int k = 0; k < box_cells.z(); ++k) {
    for (int j = 0; j < box_cells.y(); ++j) {
      for (int i = 0; i < box_cells.x(); ++i) {
        const Eigen::Vector3i c = box.first_node + Eigen::Vector3i(i, j, k);
        const int cell = c.x() + grid_cells.x() * (c.y() + grid_cells.y() * c.z());
        for (int t = 0; t < kTetsPerCell; ++t) {
          const int global = kTetsPerCell * cell + t;
          const geometry::Tet& gt = grid_mesh.tets[global];
          mesh.tets.push_back(
              {local_node(gt[0]), local_node(gt[1]), local_node(gt[2]), local_node(gt[3])});
          if (global_tets != nullptr) global_tets->push_back(global);
        }
      }
    }
  }
  return mesh;
}

}  // namespace ultrasim::sim
