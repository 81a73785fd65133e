/// @brief CellImage: an exact copy of some leaf cells of a sculpture (values, masks and the tree
/// levels that held them), taken before an edit so that undo can put those cells back.
#ifndef SCULPT_LEVELSET_CELL_IMAGE_H_
#define SCULPT_LEVELSET_CELL_IMAGE_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

/// The signed-distance contents of a set of leaf cells (8^3, origins at multiples of 8) as they
/// were when captured: per cell either the leaf (value mask and all 512 values, bit-exact) or the
/// uniform value with the tree level that held it (a leaf-level tile, or a tile of a larger node,
/// or the background with no node at all). Restoring writes exactly that back, and where a cell
/// was held by a larger node that has since been split, re-collapses the node once every cell of
/// it is uniform again, so a restored tree hashes (Sculpture::StateHash) as the captured one.
/// When the sculpture declares materials, the same cells of every fraction grid are held the same
/// way, so a restore puts back the fractions too (MaterialStateHash as captured).
/// Thread safety: a value type; Capture and Restore need the usual one-writer rule on the
/// sculpture.
class CellImage {
 public:
  CellImage() = default;

  /// Every leaf cell overlapping `box` (empty box: nothing).
  static CellImage Capture(const Sculpture& sculpture, const VoxelBox& box);

  /// Keeps only the cells listed in `cells` (sorted or not); the others are dropped.
  void Keep(const std::vector<Int3>& cells);

  /// Writes the held cells listed in `cells` back into `sculpture` (cells not held are skipped)
  /// and returns how many were written. The tracked volume is not touched (the caller owns the
  /// scalars: see ReplayState).
  size_t Restore(Sculpture& sculpture, const std::vector<Int3>& cells) const;
  /// Writes every held cell back.
  size_t RestoreAll(Sculpture& sculpture) const;

  /// Appends the held cells to `out` (for a snapshot of the server's own undo history): the
  /// signed distances, then a byte counting the fraction grids and each grid's cells.
  void AppendTo(std::string& out) const;
  /// Reads what AppendTo wrote from the front of `in` and advances it; `with_fractions` false
  /// reads the older layout without the fraction grids. Only for bytes this process's build
  /// wrote; still bounds-checked: DataLoss naming the field for a truncated or malformed image.
  static StatusOr<CellImage> ReadFrom(std::string_view& in, bool with_fractions = true);

  bool Holds(const Int3& cell) const;
  /// Origins of the held cells, sorted (z, y, x).
  std::vector<Int3> Cells() const;
  size_t cell_count() const { return sdf_.cells.size(); }
  size_t leaf_count() const { return sdf_.leaves.size(); }
  /// Fraction grids held (0: the sculpture had no materials when captured).
  size_t fraction_grids() const { return fractions_.size(); }
  /// Heap bytes held (the measure of an undo step's memory).
  size_t MemoryBytes() const;
  void Clear();

 private:
  struct Cell {
    Int3 origin;
    /// 0 leaf (index into leaves_), 1 tile of the leaf's parent, 2 tile of the parent's parent,
    /// 3 root tile, 4 background (no root entry).
    uint8_t level = 0;
    bool active = false;
    float value = 0;
    uint32_t leaf = 0;
  };
  struct Leaf {
    uint64_t mask[8];
    float values[512];
  };
  /// The cells of one grid.
  struct Part {
    std::vector<Cell> cells;  // sorted by (z, y, x)
    std::vector<Leaf> leaves;
    const Cell* Find(const Int3& origin) const;
    size_t MemoryBytes() const;
  };
  // `grid`: -1 the signed distances, m >= 0 the fractions of material m.
  static Part CapturePart(const Sculpture& sculpture, int grid,
                          const std::vector<Int3>& sorted_cells);
  static void KeepPart(Part& part, const std::vector<Int3>& sorted_keep);
  static size_t RestorePart(const Part& part, Sculpture& sculpture, int grid,
                            const std::vector<Int3>& cells);
  static void AppendPart(const Part& part, std::string& out);
  static StatusOr<Part> ReadPart(std::string_view& in);

  Part sdf_;
  std::vector<Part> fractions_;  // one per fraction grid, the same cells as sdf_
};

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_CELL_IMAGE_H_
