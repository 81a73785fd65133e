/// @brief Chunked meshing of a sculpture's zero level set: fixed cubes of voxels meshed one at a
/// time, whose meshes join without cracks when assembled.
#ifndef SCULPT_MESH_CHUNK_MESHER_H_
#define SCULPT_MESH_CHUNK_MESHER_H_

#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh {

/// Chunk edge in voxels by default: 32 = 4 x 4 x 4 OpenVDB leaves.
inline constexpr int kDefaultChunkVoxels = 32;
inline constexpr int kMinChunkVoxels = 8;
inline constexpr int kMaxChunkVoxels = 256;
/// Largest |chunk key| component accepted (keeps key * chunk_voxels far inside int).
inline constexpr int kMaxChunkKey = 1 << 20;

/// A chunk's key: the chunk covers index voxels [key * n, key * n + n) per axis, n the chunk edge
/// (so key = floor(index / n)).
struct ChunkKey {
  int x = 0, y = 0, z = 0;
  constexpr auto operator<=>(const ChunkKey&) const = default;
};

struct ChunkKeyHash {
  size_t operator()(const ChunkKey& k) const {
    uint64_t h = static_cast<uint32_t>(k.x);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<uint32_t>(k.y);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<uint32_t>(k.z);
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

struct ChunkMeshOptions {
  /// Chunk edge in voxels, a multiple of 8 (the leaf size) in [kMinChunkVoxels, kMaxChunkVoxels].
  int chunk_voxels = kDefaultChunkVoxels;
};

/// InvalidArgument naming the field, the value and the allowed range, else Ok.
Status ValidateChunkMeshOptions(const ChunkMeshOptions& options);
/// InvalidArgument for a key component outside [-kMaxChunkKey, kMaxChunkKey], else Ok.
Status ValidateChunkKey(const ChunkKey& key);

/// One chunk's share of the surface.
struct ChunkMesh {
  ChunkKey key;
  TriangleMesh mesh;
  double mesh_ms = 0;  // wall time of MeshChunk
};

/// Meshes the polygons of the zero level set that belong to chunk `key`. Each polygon of the
/// dual (volumeToMesh, adaptivity 0) mesh belongs to exactly one chunk, the one holding the floor
/// of its vertex mean in index space, so the chunks of a sculpture together hold exactly the
/// polygons of the whole-grid mesh, with bit-identical shared vertices at the seams. Quads are
/// split into two triangles as in Sculpture::ExportMesh. Cost follows the chunk: only the
/// chunk's box and a 3-voxel margin are copied out of the grid and meshed.
/// InvalidArgument for bad options or a key out of range. An empty mesh where there is no surface.
/// Reads the sculpture: not concurrently with an edit on it.
StatusOr<ChunkMesh> MeshChunk(const levelset::Sculpture& sculpture, const ChunkKey& key,
                              const ChunkMeshOptions& options = {});

/// The chunks whose mesh may change when the leaves at `dirty_leaf_origins` (8-aligned index
/// origins, as EditResult::dirty_leaves) change: a polygon depends on voxels up to 2 voxels
/// beyond its chunk, so a leaf near a chunk border dirties its neighbours too. Sorted, unique.
/// Options are assumed valid (ValidateChunkMeshOptions); with bad options returns nothing.
std::vector<ChunkKey> ChunksTouchedBy(const std::vector<levelset::Int3>& dirty_leaf_origins,
                                      const ChunkMeshOptions& options = {});

/// Every chunk that may hold surface: those within one voxel of a sign change (conservative: a
/// few of them mesh to nothing; 308 listed for 272 with faces on a radius-128 sphere). Walks every
/// leaf of the grid (40-100 ms at radius 128): for subscribing a viewer, not for the edit path;
/// after that, follow edits with ChunksTouchedBy. Sorted, unique.
/// With bad options returns nothing.
std::vector<ChunkKey> AllChunks(const levelset::Sculpture& sculpture,
                                const ChunkMeshOptions& options = {});

/// The whole-grid mesh (volumeToMesh, adaptivity 0, quads split as in MeshChunk): the reference
/// the chunks assemble to, and what the GLB export writes.
TriangleMesh MeshWhole(const levelset::Sculpture& sculpture);

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_CHUNK_MESHER_H_
