#pragma once

// How MsdsEngine splits its per-node work (internal, shared by msds.cpp and
// msds_implicit.cpp): fixed chunks, so every sum is taken in chunk order whatever thread runs
// a chunk.

#include "msds_task_team.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {

namespace msds_detail {

// Node chunks are also the explicit step's blocks: their kinetic energies are summed in order.
inline constexpr int kNodesPerChunk = 256;

inline int chunk_count(int items, int per_chunk) {
  return (items + per_chunk - 1) / per_chunk;
}

}  // namespace msds_detail

template <typename Body>
void MsdsEngine::for_each_chunk(int count, Body&& body) {
  team_->for_each(count, body);
}

}  // namespace ultrasim::sim
