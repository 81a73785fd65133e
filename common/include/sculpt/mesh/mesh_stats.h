/// @brief MeshTopology: what a viewer would see wrong with a mesh, counted: open edges,
/// non-manifold edges, separate pieces, handles, and the volume the surface encloses.
#ifndef SCULPT_MESH_MESH_STATS_H_
#define SCULPT_MESH_MESH_STATS_H_

#include <cstddef>
#include <cstdint>

#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh {

/// Topology and enclosed volume of an indexed triangle mesh. Vertices are welded by index, so
/// a mesh whose chunks repeat seam vertices must be welded first (WeldByPosition).
struct MeshTopology {
  size_t vertices = 0;             ///< vertices used by at least one face
  size_t faces = 0;                ///< non-degenerate faces (three distinct indices)
  size_t edges = 0;                ///< distinct undirected edges
  size_t boundary_edges = 0;       ///< edges with one face: holes
  size_t non_manifold_edges = 0;   ///< edges with more than two faces
  size_t inconsistent_edges = 0;   ///< edges whose two faces run the same way (flipped faces)
  size_t components = 0;           ///< face-connected pieces
  int64_t euler = 0;               ///< V - E + F
  /// Sum over components of the genus, (2 - χ_c) / 2, for closed manifold meshes; -1 otherwise.
  int64_t genus = -1;
  /// Σ (a · (b × c)) / 6 over faces: positive when faces wind counter-clockwise seen from outside.
  double signed_volume = 0.0;

  bool closed_manifold() const {
    return boundary_edges == 0 && non_manifold_edges == 0 && inconsistent_edges == 0;
  }
};

/// Counts `mesh`'s topology and signed volume. O(F log F).
MeshTopology ComputeTopology(const TriangleMesh& mesh);

/// Signed volume alone (cheaper): positive for an outward-wound closed mesh.
double SignedVolume(const TriangleMesh& mesh);

/// The same faces with vertices at bit-identical positions merged (for meshes assembled from
/// chunks, whose seam vertices repeat). Colours follow the first vertex kept.
TriangleMesh WeldByPosition(const TriangleMesh& mesh);

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_MESH_STATS_H_
