/// @brief Regions of a sculpture for replication: leaf versions, leaf records (the leaf-delta
/// wire form: exact float32 values, byte-shuffled, zstd-compressed), and hashes of leaves and
/// boxes that a replica compares with the server's.
#ifndef SCULPT_LEVELSET_REGION_H_
#define SCULPT_LEVELSET_REGION_H_

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

/// Edge of a leaf in voxels (OpenVDB's default LeafNode).
inline constexpr int kLeafDim = 8;

/// An inclusive index-space box.
struct VoxelBox {
  Int3 min{0, 0, 0};
  Int3 max{-1, -1, -1};
  bool Empty() const { return max.x < min.x || max.y < min.y || max.z < min.z; }
  bool Contains(const VoxelBox& o) const;
  bool Intersects(const VoxelBox& o) const;
  VoxelBox Intersection(const VoxelBox& o) const;
  VoxelBox Dilated(int voxels) const;
  /// Voxel count (0 when empty), saturating.
  uint64_t Volume() const;
};

/// The index box of a world box (floor/ceil), for interest regions.
VoxelBox WorldToVoxelBox(const Sculpture& sculpture, const Vec3& lo, const Vec3& hi);

/// The global sequence that last wrote each leaf (origins at multiples of 8). Leaves never
/// written since the server started have version 0.
class LeafVersions {
 public:
  void Record(const std::vector<Int3>& leaves, uint64_t seq);
  uint64_t Get(const Int3& leaf) const;
  /// Leaves written after `seq` (inside `box` when it is non-empty), sorted.
  std::vector<Int3> NewerThan(uint64_t seq, const VoxelBox& box = {}) const;
  size_t size() const { return versions_.size(); }

 private:
  std::unordered_map<uint64_t, uint64_t> versions_;
};

/// Leaf origins of every leaf cell in `box` that holds anything a replica starting from an
/// empty grid needs: a leaf, or a tile of another value than the background (inside). Walks
/// the leaves and tiles of the tree, not the box's voxels.
std::vector<Int3> OccupiedLeafCells(const Sculpture& sculpture, const VoxelBox& box);

/// Every leaf cell of `box` (aligned to 8), occupied or not: for a replica replacing a region.
std::vector<Int3> AllLeafCells(const VoxelBox& box);

struct LeafRecordStats {
  uint64_t records = 0;
  uint64_t leaves = 0;   // records carrying voxel values
  uint64_t uniform = 0;  // records carrying one value (a tile or the background)
  uint64_t raw_bytes = 0;
  uint64_t compressed_bytes = 0;
};

/// Encodes the state of the given leaf cells: per cell its origin, its version (from
/// `versions`, 0 without), and either the leaf (value mask, signs of inactive voxels, the active
/// values as float32, exact) or its uniform value. Byte-shuffled, then zstd at `level`.
std::string EncodeLeafRecords(const Sculpture& sculpture, const std::vector<Int3>& cells,
                              const LeafVersions* versions, int level = 3,
                              LeafRecordStats* stats = nullptr);

struct LeafApplyResult {
  uint64_t records = 0;
  uint64_t max_version = 0;
  std::vector<Int3> cells;
};

/// Writes decoded records into the sculpture (leaves replaced whole; uniform cells become
/// tiles, as the server's write-back collapses them). Untrusted input: DataLoss naming the
/// offending field for a bad magic, size, count, origin or value; the sculpture is unchanged
/// then. Cells outside `clip` (when non-empty) are skipped.
StatusOr<LeafApplyResult> ApplyLeafRecords(Sculpture& sculpture, std::string_view bytes,
                                           const VoxelBox& clip = {});

/// Hash of the given leaf cells' contents (values and masks, or uniform values), in the given
/// order. Server and replica compute it over an edit's dirty leaves.
uint64_t LeavesHash(const Sculpture& sculpture, const std::vector<Int3>& cells);

/// Hash of every voxel value in `box`, independent of the tree's structure (tiles or leaves).
uint64_t RegionHash(const Sculpture& sculpture, const VoxelBox& box);

/// Sets every voxel of `box` to the inactive background (a replica dropping a region before it
/// loads it anew).
void ClearRegion(Sculpture& sculpture, const VoxelBox& box);

/// An empty sculpture (no voxels) with the given voxel size, band and name: a partial replica's
/// starting point.
StatusOr<Sculpture> MakeEmptySculpture(const SculptureOptions& options);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_REGION_H_
