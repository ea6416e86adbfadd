#pragma once

#include <Eigen/Core>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::sim {

// One sub-volume of a grid split for volume stitching: the box of grid nodes it owns,
// [first_node, first_node + nodes) on each axis, and its place in the split.
struct SubVolumeBox {
  Eigen::Vector3i index = Eigen::Vector3i::Zero();  // position in the sub-volume grid
  Eigen::Vector3i first_node = Eigen::Vector3i::Zero();
  Eigen::Vector3i nodes = Eigen::Vector3i::Constant(2);

  int node_count() const { return nodes.prod(); }
  bool contains(const Eigen::Vector3i& grid_node) const {
    return (grid_node.array() >= first_node.array()).all() &&
           (grid_node.array() < (first_node + nodes).array()).all();
  }
};

// Splits a grid of `grid_nodes` nodes into sub_volumes.x × .y × .z boxes, neighbours sharing
// `overlap_nodes` node layers (the published split: 2, so the seam stays continuous). The cells
// left after the overlaps are shared out as evenly as rounding allows: 52 nodes in 5 with an
// overlap of 2 give five boxes of 12 nodes, starting every 10. In x-fastest order. Throws
// std::invalid_argument when a count is below 1, the overlap below 1, or a box would have fewer
// than overlap_nodes + 1 nodes on an axis it is split along. Allocates.
std::vector<SubVolumeBox> split_grid(const Eigen::Vector3i& grid_nodes,
                                     const Eigen::Vector3i& sub_volumes, int overlap_nodes);

// The sub-mesh of one box: its nodes (in the box's own x-fastest order) and grid_mesh's tets of
// its cells, the very same tets (make_grid_tet_mesh alternates its cell split with the cell's
// parity: a box meshed on its own from an odd node would cut its cells the other way).
// `grid_mesh` must be make_grid_tet_mesh(grid) (std::invalid_argument otherwise); `global_tets`
// (optional) receives each sub-mesh tet's index in it. Allocates.
geometry::TetMesh extract_sub_mesh(const geometry::GridSpec& grid,
                                   const geometry::TetMesh& grid_mesh, const SubVolumeBox& box,
                                   std::vector<int>* global_tets = nullptr);

}  // namespace ultrasim::sim
