/// @brief Chunked meshing: copy a chunk's box plus a margin out of the grid, mesh the copy with
/// volumeToMesh, keep the polygons the chunk owns.
#include "sculpt/mesh/chunk_mesher.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "levelset/sculpture_grid.h"
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
// only on that cell's 8 corner values at adaptivity 0). The copy keeps whole leaves (exact
// values out to the leaf boundary) but only the voxels within kMargin of the chunk stay active,
// which bounds what volumeToMesh meshes; the spurious surface where the copy ends lies beyond
// the leaf boundary, out of every owned polygon's reach.
constexpr int kReach = 2;
constexpr int kMargin = kReach + 1;

int FloorDiv(int a, int n) { return a >= 0 ? a / n : -((-a + n - 1) / n); }

// Splits quads as Sculpture::ExportMesh does and keeps the polygons `keep` accepts, renumbering
// the vertices they use in order of first use. volumeToMesh winds its polygons clockwise seen
// from outside; every mesh leaving here is wound counter-clockwise (glTF's and three.js's front
// faces, positive signed volume), so each polygon's order is reversed here and only here.
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
    for (int c : {0, 2, 1, 0, 3, 2}) use(q[c]);
  }
  for (const openvdb::Vec3I& t : tris) {
    if (!keep(t.asPointer(), 3)) continue;
    for (int c : {0, 2, 1}) use(t[c]);
  }
  return out;
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
      return Outside(std::string(field), std::to_string(v),
                     std::string("[") + std::to_string(-kMaxChunkKey) + ", " +
                         std::to_string(kMaxChunkKey) + "]");
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
  const FloatGrid& grid = levelset::internal::GridOf(sculpture);
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
  const FloatGrid& grid = levelset::internal::GridOf(sculpture);
  FloatGrid::ConstAccessor acc = grid.getConstAccessor();
  constexpr int kDim = static_cast<int>(FloatLeaf::DIM);
  for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
    // Bounding box of the voxels p whose edge to p + e_axis changes sign (active or not: a
    // superset of the edges volumeToMesh meshes). Edges entering the leaf from a tile below it
    // are found here too; from a leaf below, by that leaf.
    const Coord o = leaf->origin();
    const float* v = leaf->buffer().data();
    bool any_in = false, any_out = false;
    for (openvdb::Index i = 0; i < FloatLeaf::SIZE; ++i) (v[i] < 0.f ? any_in : any_out) = true;
    // A leaf of one sign can only meet the surface on its faces.
    const bool uniform = !(any_in && any_out);
    auto on_face = [](int c) { return c == 0 || c == kDim - 1; };
    // The six face neighbours, probed once: a leaf's values, or a tile's sign.
    const float* hi_leaf[3];
    bool hi_tile_in[3], lo_tile[3], lo_tile_in[3];
    for (int axis = 0; axis < 3; ++axis) {
      Coord up = o, down = o;
      up[axis] += kDim;
      down[axis] -= kDim;
      const FloatLeaf* u = acc.probeConstLeaf(up);
      hi_leaf[axis] = u ? u->buffer().data() : nullptr;
      hi_tile_in[axis] = u ? false : acc.getValue(up) < 0.f;
      lo_tile[axis] = acc.probeConstLeaf(down) == nullptr;
      lo_tile_in[axis] = lo_tile[axis] && acc.getValue(down) < 0.f;
    }
    // Range of the cells that polygons on these edges can be owned by: the polygon on the edge
    // from p along `axis` has its vertex mean in [p - 1, p + 0.5] across the edge and in
    // [p, p + 1] along it (its four cells' vertices lie in those cells).
    Coord lo(INT32_MAX), hi(INT32_MIN);
    auto add = [&](const Coord& p, int axis) {
      Coord a = p.offsetBy(-1), b = p;
      a[axis] += 1;
      b[axis] += 1;
      lo.minComponent(a);
      hi.maxComponent(b);
    };
    for (int i = 0; i < kDim; ++i) {
      for (int j = 0; j < kDim; ++j) {
        for (int k = 0; k < kDim; ++k) {
          if (uniform && !on_face(i) && !on_face(j) && !on_face(k)) continue;
          const Coord c(i, j, k);
          const bool in = v[FloatLeaf::coordToOffset(c)] < 0.f;
          for (int axis = 0; axis < 3; ++axis) {
            Coord q = c;
            q[axis] += 1;
            bool next_in;
            if (q[axis] < kDim) {
              next_in = v[FloatLeaf::coordToOffset(q)] < 0.f;
            } else if (hi_leaf[axis]) {
              q[axis] = 0;
              next_in = hi_leaf[axis][FloatLeaf::coordToOffset(q)] < 0.f;
            } else {
              next_in = hi_tile_in[axis];
            }
            if (in != next_in) add(o + c, axis);
            // The edge from a tile voxel below the leaf's low face (a leaf below finds it itself).
            if (c[axis] == 0 && lo_tile[axis] && lo_tile_in[axis] != in) {
              Coord below = o + c;
              below[axis] -= 1;
              add(below, axis);
            }
          }
        }
      }
    }
    if (lo.x() > hi.x()) continue;
    for (int z = FloorDiv(lo.z(), n); z <= FloorDiv(hi.z(), n); ++z) {
      for (int y = FloorDiv(lo.y(), n); y <= FloorDiv(hi.y(), n); ++y) {
        for (int x = FloorDiv(lo.x(), n); x <= FloorDiv(hi.x(), n); ++x) {
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
  openvdb::tools::volumeToMesh(levelset::internal::GridOf(sculpture), points, tris, quads, 0.0, 0.0);
  return Collect(points, tris, quads, [](const openvdb::Index32*, int) { return true; });
}

}  // namespace sculpt::mesh
