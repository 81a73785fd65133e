/// @brief Editing a composite model through validated intents (seed 001 §8.1, §10.4): the
/// simplified grid with automatic C1 maintenance (a C1 corner moves its 26 neighbours; a face,
/// edge or vertex neighbour moves 17, 11 or 7 others by δ·Π(d_a e_a)), and material edits (§8.2).
#ifndef SCULPT_HETERO_GRID_EDITOR_H_
#define SCULPT_HETERO_GRID_EDITOR_H_

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/corner_block.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::hetero {

/// What a sculptor asks for (it may come off the wire; ExpandIntent validates every field).
struct EditIntent {
  uint32_t corner = 0;                 // pool index of a corner coefficient
  std::array<int, 3> offset{0, 0, 0};  // neighbour offset e ∈ {−1,0,1}³ in the corner block
  Vec3 displacement;                   // δ in model units
  /// At an irregular corner the offset is read in this cell's index space (−1 = no cell).
  int cell = -1;
  /// Continuity flags to set at the corner before the move (geometry C1 is then enforced by
  /// (7.6) from the lower side, material C1 by the copy rule).
  std::optional<CornerFlags> set_flags = std::nullopt;
};

/// One coefficient's displacement in an expanded edit.
struct CoefficientMove {
  uint32_t coef;
  Vec3 delta;
};

/// The largest |δ| component an intent may carry (model units).
inline constexpr double kMaxDisplacement = 1e6;

/// Expands an intent deterministically (ascending coefficient order) into moves. InvalidArgument
/// naming the field when the corner, offset, displacement or cell is out of range; a
/// FailedPrecondition IRREGULAR_CORNER when geometry C1 is asked at an irregular corner.
StatusOr<std::vector<CoefficientMove>> ExpandIntent(const CompositeModel& model,
                                                    const EditIntent& intent);

/// The outcome of applying an intent.
struct EditOutcome {
  bool applied = false;
  Rejection rejection;                   // why not, when !applied and the intent was well formed
  std::vector<CoefficientMove> moves;    // what moved (empty when refused)
  std::vector<int> touched_cells;        // cells re-validated
};

/// Validates, expands and applies an intent, then re-checks the touched cells and their overlaps
/// with `checker`; an edit that leaves the model invalid is undone and refused with the reason.
/// Returns InvalidArgument for a malformed intent (the model is then unchanged).
StatusOr<EditOutcome> ApplyIntent(CompositeModel* model, ValidityChecker* checker,
                                  const EditIntent& intent);

/// Makes a regular corner geometrically C1 by (7.6) h(+1) = 2h(0) − h(−1), the lower side
/// being the master, axis by axis. IRREGULAR_CORNER when the corner is not regular.
Status EnforceGeometryC1(CompositeModel* model, uint32_t corner);

// ----------------------------------- material edits (§8.2) ---------------------------------

/// Sets one coefficient's distribution (validated: InvalidArgument naming "fractions").
Status SetPointMaterial(CompositeModel* model, uint32_t coef, std::span<const double> a);
/// Sets all 64 coefficients of a cell (constant A). Coefficients shared with other cells are
/// copied first, so neighbours keep theirs: geometry stays C0, material becomes discontinuous.
Status SetCellMaterial(CompositeModel* model, int cell, std::span<const double> a);
/// Sets every coefficient whose position lies in `region` (inclusive).
Status SetRegionMaterial(CompositeModel* model, const Aabb& region, std::span<const double> a);
/// The C1 copy rule (§7.4, §8.2): the corner's distribution `a` on the corner and its 7 immediate
/// neighbours in each selected cell (empty = every cell at the corner). Coefficients shared with
/// unselected cells are copied, so the gradation is discontinuous towards them (Fig. 8.7).
Status SetCornerMaterial(CompositeModel* model, uint32_t corner, std::span<const double> a,
                         std::span<const int> selected_cells = {});

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_GRID_EDITOR_H_
