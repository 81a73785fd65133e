/// @brief TriangleMesh: an indexed triangle mesh in world units, the value chunk meshing,
/// the Draco chunk codec and the GLB writer pass around.
#ifndef SCULPT_MESH_TRIANGLE_MESH_H_
#define SCULPT_MESH_TRIANGLE_MESH_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sculpt::mesh {

/// Vertices as x, y, z floats (world units); faces as three vertex indices each, wound
/// counter-clockwise seen from outside the material (glTF's front faces; positive signed volume,
/// mesh_stats.h). openvdb::tools::volumeToMesh winds the other way; chunk_mesher.cc reverses it.
/// Thread safety: a value type.
struct TriangleMesh {
  std::vector<float> positions;
  std::vector<uint32_t> indices;
  /// Optional per-vertex colours, r, g, b in [0, 1] (3 per vertex), or empty: mixed from the
  /// material fractions when the sculpture declares materials (vertex_colours.h).
  std::vector<float> colours;

  size_t vertex_count() const { return positions.size() / 3; }
  size_t face_count() const { return indices.size() / 3; }
  bool empty() const { return indices.empty(); }
};

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_TRIANGLE_MESH_H_
