/// @brief Helpers shared by the material sources (materials.cc, materials_voxelize.cc).
#ifndef SCULPT_LEVELSET_MATERIALS_INTERNAL_H_
#define SCULPT_LEVELSET_MATERIALS_INTERNAL_H_

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/region.h"
#include "sculpture_impl.h"

namespace sculpt::levelset::internal {

/// Brings a fraction vector back onto the simplex and stores it as float: the Euclidean
/// projection (seed 001 §10.1) when it overshot (a negative or non-finite entry, or a sum off by
/// more than kFractionTolerance), a rescale when it is off by rounding only, so float rounding
/// never accumulates over repeated edits. `v` is overwritten with the projected doubles.
void ToSimplexFloat(std::span<double> v, std::span<float> out);

// The materials block of a leaf-record payload (region.cc writes it after the SDF's values when
// materials are declared, magic SLR2): uint8 n; per cell and material a type byte (0 uniform,
// 1 leaf) and, for a uniform cell, its float; then the 512 floats of every leaf, byte-shuffled
// in four planes as the SDF's values are.

/// Appends the block for `cells` to `out`.
void EncodeMaterialCells(const Sculpture::Impl& impl, const std::vector<Int3>& cells,
                         std::string& out);

/// A decoded, validated block.
struct MaterialCells {
  size_t n = 0;
  std::vector<uint8_t> type;   // cells x n
  std::vector<float> uniform;  // cells x n (used where type is uniform)
  std::vector<size_t> first;   // cells x n: offset into values (leaves)
  std::vector<float> values;
};

/// Untrusted input: DataLoss naming the field, value and range for a material count unlike the
/// sculpture's, a bad type, a size mismatch, or any voxel whose fraction vector is not finite,
/// has an entry outside [-1e-6, 1 + 1e-6] or does not sum to 1 within 1e-6.
StatusOr<MaterialCells> DecodeMaterialCells(const Sculpture::Impl& impl, std::string_view block,
                                            size_t cells);

/// Writes record `record` of a decoded block at leaf cell `origin` (leaves replaced whole,
/// uniform cells become tiles).
void ApplyMaterialCell(Sculpture::Impl& impl, const MaterialCells& cells, size_t record,
                       const Int3& origin);

/// Hash of the fractions of the given cells, independent of masks and of tile levels (a leaf's
/// 512 values, or the value of the tile covering the cell); 0 without materials.
uint64_t MaterialCellsHash(const Sculpture::Impl& impl, const std::vector<Int3>& cells);

/// Sets every fraction of `box` to its grid's background (a replica dropping a region).
void ClearMaterialRegion(Sculpture::Impl& impl, const VoxelBox& box);

}  // namespace sculpt::levelset::internal

#endif  // SCULPT_LEVELSET_MATERIALS_INTERNAL_H_
