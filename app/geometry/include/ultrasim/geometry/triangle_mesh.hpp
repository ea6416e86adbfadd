#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace ultrasim::geometry {

using Triangle =
    std::array<std::int32_t, 3>;  // vertex indices, counter-clockwise seen from outside

// An indexed triangle surface in millimetres. Vertices are shared (welded) between the triangles
// that meet at them, so topology checks and smoothing see one surface, not a triangle soup.
// Double precision like TetMesh: the surface is embedded in the tet mesh by barycentric
// coordinates and must reproduce its rest positions exactly; a renderer converts to float itself.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices_mm;
  std::vector<Triangle> triangles;

  int vertex_count() const { return static_cast<int>(vertices_mm.size()); }
  int triangle_count() const { return static_cast<int>(triangles.size()); }
};

// Area-weighted vertex normals (unit length; zero for a vertex no non-degenerate triangle uses) of
// the triangles at the given positions, written to normals_out (positions.size() entries). Takes
// positions separately so a caller can refresh normals of an embedded surface every frame. Never
// allocates; any thread, as long as no other thread writes normals_out or reads it meanwhile.
void compute_vertex_normals(std::span<const Eigen::Vector3d> positions_mm,
                            std::span<const Triangle> triangles,
                            std::span<Eigen::Vector3d> normals_out);

// The same, returned in a new vector. Allocates.
std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh);

// compute_vertex_normals in two passes that threads can share by ranges: the triangles' normals
// (each triangle's own, by triangle range), then each vertex's sum of its triangles' normals (by
// vertex range). A vertex adds its triangles in triangle order, as compute_vertex_normals does,
// so the normals are the same bits. One pass over the triangles on one thread is the frame's
// largest surface's cost (the large case's bone: 17,000 triangles, 0.23 ms); split, both threads
// share it.
class SharedVertexNormals {
 public:
  // Which triangles meet at each vertex. Allocates; triangles must index below vertex_count.
  SharedVertexNormals(int vertex_count, std::span<const Triangle> triangles);

  int vertex_count() const { return static_cast<int>(first_incident_.size()) - 1; }
  int triangle_count() const { return static_cast<int>(triangles_.size()); }

  // The first pass, triangles [begin, end), at the given positions (vertex_count entries). Never
  // allocates; threads may run disjoint ranges at once.
  void triangle_normals(std::span<const Eigen::Vector3d> positions_mm, int begin, int end);
  // The second, vertices [begin, end), once every triangle's first pass is done: unit normals (zero
  // where no non-degenerate triangle meets) written to normals_out[begin, end). Never allocates;
  // threads may run disjoint ranges at once.
  void vertex_normals(int begin, int end, std::span<Eigen::Vector3d> normals_out) const;

 private:
  std::vector<Triangle> triangles_;
  std::vector<int> first_incident_;  // vertex v's triangles: incident_[first_[v], first_[v + 1])
  std::vector<int> incident_;        // in triangle order, a triangle once per corner it has there
  std::vector<Eigen::Vector3d> triangle_normals_;  // area-weighted (twice the area)
};

// Volume enclosed by a closed surface, by the divergence theorem (sum over triangles of the signed
// volume of the tet the triangle forms with the origin), in mm³. Positive when the triangles face
// outward; meaningless for an open surface. Never allocates; any thread.
double enclosed_volume_mm3(std::span<const Eigen::Vector3d> positions_mm,
                           std::span<const Triangle> triangles);
double enclosed_volume_mm3(const TriangleMesh& mesh);

// Total triangle area in mm². Never allocates; any thread.
double surface_area_mm2(std::span<const Eigen::Vector3d> positions_mm,
                        std::span<const Triangle> triangles);
double surface_area_mm2(const TriangleMesh& mesh);

// What check_closed_oriented found. Directed edges are the (a → b) sides of each triangle in its
// winding order; an undirected edge is the pair {a, b}.
struct MeshTopologyReport {
  int boundary_edges = 0;      // undirected edges used by one triangle only (holes)
  int non_manifold_edges = 0;  // undirected edges used by three or more triangles
  int misoriented_edges = 0;   // edges used twice in the same direction (flipped neighbours)
  int degenerate_triangles =
      0;  // triangles repeating a vertex index, or with an index out of range

  // Every edge shared by exactly two triangles with opposite directions, no degenerate triangles.
  bool closed_and_oriented() const {
    return boundary_edges == 0 && non_manifold_edges == 0 && misoriented_edges == 0 &&
           degenerate_triangles == 0;
  }
};

// Checks that the surface is closed (watertight) and consistently oriented: every edge is shared by
// exactly two triangles that traverse it in opposite directions. Says nothing about which way the
// surface faces; enclosed_volume_mm3() > 0 tells that. Allocates (an edge list); any thread.
MeshTopologyReport check_closed_oriented(const TriangleMesh& mesh);

}  // namespace ultrasim::geometry
