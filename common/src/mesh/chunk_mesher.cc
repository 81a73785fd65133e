/// @brief Chunked meshing: copy a chunk's box plus a margin out of the grid, mesh the copy with
/// volumeToMesh, keep the polygons the chunk owns.
#include "sculpt/mesh/chunk_mesher.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <unordered_map>
#include <utility>

#include "levelset/sculpture_impl.h"
#include "sculpt/core/check.h"

namespace sculpt::mesh {
namespace {

using openvdb::Coord;
using openvdb::CoordBBox;
using openvdb::FloatGrid;
using FloatLeaf = openvdb::FloatTree::LeafNodeType;

// A polygon of the dual mesh owned by a chunk has its vertex mean inside the chunk. Its crossing
// edge then lies within one voxel of the chunk and its four cells' corners within two, so the
// polygon reads voxels at most kReach voxels outside the chunk (the vertex of a cell depends
// only on that cell's 8 corner values at adaptivity 0). The copy adds one more voxel so that
// the spurious surface where the copy ends never reaches an owned polygon.
constexpr int kReach = 2;
constexpr int kMargin = kReach + 1;

int FloorDiv(int a, int n) { return a >= 0 ? a / n : -((-a + n - 1) / n); }

// Splits quads as Sculpture::ExportMesh does and keeps the polygons `keep` accepts, renumbering
// the vertices they use in order of first use.
template <typename Keep>
TriangleMesh Collect(const std::vector<openvdb::Vec3s>& points,
                     const std::vector<openvdb::Vec3I>& tris,
                     const std::vector<openvdb::Vec4I>& quads, Keep&& keep) {
  TriangleMesh out;
  std::vector<uint32_t> remap(points.size(), UINT32_MAX);
  auto use = [&](uint32_t v) {
    if (remap[v] == UINT32_MAX) {
      remap[v] = static_cast<uint32_t>(out.positions.size() / 3);
      out.positions.insert(out.positions.end(), {points[v][0], points[v][1], points[v][2]});
    }
    out.indices.push_back(remap[v]);
  };
  for (const openvdb::Vec4I& q : quads) {
    if (!keep(q.asPointer(), 4)) continue;
    for (int c : {0, 1, 2, 0, 2, 3}) use(q[c]);
  }
  for (const openvdb::Vec3I& t : tris) {
    if (!keep(t.asPointer(), 3)) continue;
    for (int c : {0, 1, 2}) use(t[c]);
  }
  return out;
}

// True if some value of the leaf is inside (below zero) and some is not.
struct SignFlags {
  bool inside = false, outside = false;
};
SignFlags LeafSigns(const FloatLeaf& leaf) {
  SignFlags f;
  const float* v = leaf.buffer().data();
  for (openvdb::Index i = 0; i < FloatLeaf::SIZE; ++i) {
    (v[i] < 0.f ? f.inside : f.outside) = true;
    if (f.inside && f.outside) break;
  }
  return f;
}

}  // namespace

Status ValidateChunkMeshOptions(const ChunkMeshOptions& options) {
  SCULPT_RETURN_IF_ERROR(CheckRange("ChunkMeshOptions.chunk_voxels", options.chunk_voxels,
                                    kMinChunkVoxels, kMaxChunkVoxels));
  if (options.chunk_voxels % 8 != 0) {
    return InvalidArgument("ChunkMeshOptions.chunk_voxels=" + std::to_string(options.chunk_voxels) +
                           " is not a multiple of 8 in [" + std::to_string(kMinChunkVoxels) +
                           ", " + std::to_string(kMaxChunkVoxels) + "]");
  }
  return Status::Ok();
}

Status ValidateChunkKey(const ChunkKey& key) {
  for (const auto& [field, v] : {std::pair{"ChunkKey.x", key.x}, std::pair{"ChunkKey.y", key.y},
                                  std::pair{"ChunkKey.z", key.z}}) {
    if (v < -kMaxChunkKey || v > kMaxChunkKey) {
      return InvalidArgument(std::string(field) + "=" + std::to_string(v) + " outside [" +
                             std::to_string(-kMaxChunkKey) + ", " + std::to_string(kMaxChunkKey) +
                             "]");
    }
  }
  return Status::Ok();
}

StatusOr<ChunkMesh> MeshChunk(const levelset::Sculpture& sculpture, const ChunkKey& key,
                              const ChunkMeshOptions& options) {
  SCULPT_RETURN_IF_ERROR(ValidateChunkMeshOptions(options));
  SCULPT_RETURN_IF_ERROR(ValidateChunkKey(key));
  const auto t0 = std::chrono::steady_clock::now();
  const int n = options.chunk_voxels;
  const FloatGrid& grid = *sculpture.impl().grid;
  const Coord c0(key.x * n, key.y * n, key.z * n);
  const Coord c1 = c0.offsetBy(n - 1);
  const CoordBBox box(c0.offsetBy(-kMargin), c1.offsetBy(kMargin));

  // The copy keeps the grid's index space (same transform), so every vertex is computed from the
  // same values at the same coordinates as in the whole-grid mesh and comes out bit-identical.
  FloatGrid::Ptr local = FloatGrid::create(grid.background());
  local->setTransform(grid.transform().copy());
  local->setGridClass(openvdb::GRID_LEVEL_SET);
  auto& tree = local->tree();
  const auto& src = grid.tree();
  FloatGrid::ConstAccessor acc = grid.getConstAccessor();
  const Coord lo = box.min() & ~7, hi = box.max() & ~7;
  for (int z = lo.z(); z <= hi.z(); z += 8) {
    for (int y = lo.y(); y <= hi.y(); y += 8) {
      for (int x = lo.x(); x <= hi.x(); x += 8) {
        const Coord origin(x, y, z);
        if (const FloatLeaf* leaf = src.probeConstLeaf(origin)) {
          auto* copy = new FloatLeaf(*leaf);
          // Voxels outside the box keep their values (cells at the box border read them) but go
          // inactive, so volumeToMesh does not mesh the leaf's far side.
          if (!box.isInside(copy->getNodeBoundingBox())) {
            for (auto it = copy->beginValueOn(); it; ++it) {
              if (!box.isInside(it.getCoord())) it.setValueOff();
            }
          }
          tree.addLeaf(copy);
        } else {
          float v = 0;
          acc.probeValue(origin, v);
          if (v != grid.background()) tree.addTile(1, origin, v, false);
        }
      }
    }
  }

  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*local, points, tris, quads, 0.0, 0.0);

  const openvdb::math::Transform& xf = grid.transform();
  auto owned = [&](const openvdb::Index32* v, int count) {
    openvdb::Vec3d sum(0.0);
    for (int i = 0; i < count; ++i) sum += xf.worldToIndex(openvdb::Vec3d(points[v[i]]));
    sum /= static_cast<double>(count);
    const Coord cell = Coord::floor(sum);
    return FloorDiv(cell.x(), n) == key.x && FloorDiv(cell.y(), n) == key.y &&
           FloorDiv(cell.z(), n) == key.z;
  };
  ChunkMesh out;
  out.key = key;
  out.mesh = Collect(points, tris, quads, owned);
  out.mesh_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::vector<ChunkKey> ChunksTouchedBy(const std::vector<levelset::Int3>& dirty_leaf_origins,
                                      const ChunkMeshOptions& options) {
  std::vector<ChunkKey> keys;
  if (!ValidateChunkMeshOptions(options).ok()) return keys;
  const int n = options.chunk_voxels;
  for (const levelset::Int3& o : dirty_leaf_origins) {
    // The leaf's voxels [o, o + 7] are read by the chunks within kReach voxels of them.
    const int x0 = FloorDiv(o.x - kReach, n), x1 = FloorDiv(o.x + 7 + kReach, n);
    const int y0 = FloorDiv(o.y - kReach, n), y1 = FloorDiv(o.y + 7 + kReach, n);
    const int z0 = FloorDiv(o.z - kReach, n), z1 = FloorDiv(o.z + 7 + kReach, n);
    for (int z = z0; z <= z1; ++z) {
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) keys.push_back({x, y, z});
      }
    }
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

std::vector<ChunkKey> AllChunks(const levelset::Sculpture& sculpture,
                                const ChunkMeshOptions& options) {
  std::vector<ChunkKey> keys;
  if (!ValidateChunkMeshOptions(options).ok()) return keys;
  const int n = options.chunk_voxels;
  const FloatGrid& grid = *sculpture.impl().grid;
  const auto& tree = grid.tree();
  FloatGrid::ConstAccessor acc = grid.getConstAccessor();
  std::unordered_map<Coord, SignFlags> signs;
  auto signs_of = [&](const Coord& origin) -> SignFlags {
    if (auto it = signs.find(origin); it != signs.end()) return it->second;
    SignFlags f;
    if (const FloatLeaf* leaf = tree.probeConstLeaf(origin)) {
      f = LeafSigns(*leaf);
    } else {
      (acc.getValue(origin) < 0.f ? f.inside : f.outside) = true;
    }
    signs.emplace(origin, f);
    return f;
  };
  for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
    const Coord o = leaf->origin();
    const SignFlags f = signs_of(o);
    // A crossing touches this leaf if its own values change sign or a face neighbour has the
    // other sign (the crossing then sits on the shared face).
    bool surface = f.inside && f.outside;
    for (int axis = 0; axis < 3 && !surface; ++axis) {
      for (int step : {-8, 8}) {
        Coord nb = o;
        nb[axis] += step;
        const SignFlags g = signs_of(nb);
        if ((f.inside && g.outside) || (f.outside && g.inside)) surface = true;
      }
    }
    if (!surface) continue;
    // Polygons from crossings at voxels [o - 1, o + 8] have vertex means in [o - 2, o + 9].
    for (int z = FloorDiv(o.z() - 2, n); z <= FloorDiv(o.z() + 9, n); ++z) {
      for (int y = FloorDiv(o.y() - 2, n); y <= FloorDiv(o.y() + 9, n); ++y) {
        for (int x = FloorDiv(o.x() - 2, n); x <= FloorDiv(o.x() + 9, n); ++x) {
          keys.push_back({x, y, z});
        }
      }
    }
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

TriangleMesh MeshWhole(const levelset::Sculpture& sculpture) {
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*sculpture.impl().grid, points, tris, quads, 0.0, 0.0);
  return Collect(points, tris, quads, [](const openvdb::Index32*, int) { return true; });
}

}  // namespace sculpt::mesh
