/// @brief The 3×3×3 block of coefficients around a corner point (seed 001 §8.1) and the per-corner
/// C0/C1 continuity classification, separately for geometry and material (§7.4).
#ifndef SCULPT_HETERO_CORNER_BLOCK_H_
#define SCULPT_HETERO_CORNER_BLOCK_H_

#include <array>
#include <cstdint>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"

namespace sculpt::hetero {

/// Offset d ∈ {−1,0,1}³ of a block position from the corner, as an index 0..26.
constexpr int BlockIndex(int dx, int dy, int dz) { return (dx + 1) * 9 + (dy + 1) * 3 + (dz + 1); }

/// The cells meeting at a corner point and the coefficients at each of the 27 block positions.
/// A cell contributes its corner and its 7 immediate neighbours (the 2×2×2 block at that corner).
/// Several coefficients may sit at one block position: one per cell when cells do not share pool
/// entries (a material discontinuity keeps positions equal but entries distinct).
struct CornerBlock {
  uint32_t corner = 0;             // the key coefficient (lowest pool index at the corner)
  std::vector<int> cells;          // ascending
  std::array<int, 8> octant_cell;  // octant bits (x+, y+, z+) -> cell, or -1
  std::array<std::vector<uint32_t>, 27> coefs;  // ascending, deduplicated
  /// The cells sit in distinct octants with consistent parametric axes and form a box-shaped
  /// block (1, 2, 4 or 8 cells). Automatic C1 needs a regular corner (§8.1, claim 23).
  bool regular = false;
  /// Valence: how many cells meet at the corner point.
  int valence() const { return static_cast<int>(cells.size()); }
};

/// Continuity at a corner (§7.4): C0 = coefficients at one block position coincide; C1 = (7.5)
/// v_l = v_m along every axis through the block, for positions and for fractions separately.
struct CornerContinuity {
  bool geometry_c0 = false;
  bool geometry_c1 = false;
  bool material_c0 = false;
  bool material_c1 = false;
};

/// The block around the corner point of coefficient `corner`. NotFound when no cell has that
/// coefficient (or one at the same position) as a corner.
StatusOr<CornerBlock> BuildCornerBlock(const CompositeModel& model, uint32_t corner,
                                       double tol = 1e-9);

/// Classifies a block; C1 needs C0 and at least one complete line of three positions.
CornerContinuity ClassifyCorner(const CompositeModel& model, const CornerBlock& block,
                                double tol = 1e-9);

/// Every corner point of the model, by its key coefficient (ascending).
std::vector<uint32_t> CornerPoints(const CompositeModel& model, double tol = 1e-9);

/// Sets the corner's flags from what holds (§9.1 step 2, claim 31): geometry_c1 when the block is
/// regular and geometrically C1, material_c1 likewise. Returns the flags set.
CornerFlags ClassifyAndFlag(CompositeModel* model, uint32_t corner, double tol = 1e-9);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_CORNER_BLOCK_H_
