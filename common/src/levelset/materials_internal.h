/// @brief Helpers shared by the material sources (materials.cc, materials_voxelize.cc).
#ifndef SCULPT_LEVELSET_MATERIALS_INTERNAL_H_
#define SCULPT_LEVELSET_MATERIALS_INTERNAL_H_

#include <span>

namespace sculpt::levelset::internal {

/// Brings a fraction vector back onto the simplex and stores it as float: the Euclidean
/// projection (seed 001 §10.1) when it overshot (a negative or non-finite entry, or a sum off by
/// more than kFractionTolerance), a rescale when it is off by rounding only, so float rounding
/// never accumulates over repeated edits. `v` is overwritten with the projected doubles.
void ToSimplexFloat(std::span<double> v, std::span<float> out);

}  // namespace sculpt::levelset::internal

#endif  // SCULPT_LEVELSET_MATERIALS_INTERNAL_H_
