/// @brief Material distributions (seed 001 §4.2): validation against the simplex V (4.2), the
/// combination operator a ⊕α b (4.3) and the Euclidean projection back onto V.
#ifndef SCULPT_HETERO_MATERIAL_H_
#define SCULPT_HETERO_MATERIAL_H_

#include <span>
#include <string>
#include <vector>

#include "sculpt/core/status.h"

namespace sculpt::hetero {

/// A material distribution: one volume fraction per primary material (seed 001 (4.1)).
using Fractions = std::vector<double>;

/// How far the sum of a distribution may stray from 1 (the wire tolerance).
inline constexpr double kSimplexSumTolerance = 1e-6;
/// The most primary materials a model may declare (bounds what the wire can ask for).
inline constexpr int kMaxMaterials = 16;

/// Ok when `a` holds `materials` finite fractions, each >= 0 and summing to 1 within
/// kSimplexSumTolerance (seed 001 (4.2)). Otherwise InvalidArgument naming `field`, the
/// offending value and the allowed range, e.g. "cell[3].a[1]=-0.2 outside [0, 1]".
Status ValidateFractions(const std::string& field, std::span<const double> a, int materials);

/// a ⊕α b = α·a + (1−α)·b (seed 001 (4.3)). InvalidArgument when α is not in [0, 1], the sizes
/// differ, or either input is not in V: V is closed under ⊕α only for α ∈ [0, 1].
StatusOr<Fractions> Mix(std::span<const double> a, std::span<const double> b, double alpha);

/// In-place Mix without validation, for hot loops whose inputs are already known to be in V
/// (the paint brush): out = α·a + (1−α)·b, clamped to [0, 1] and renormalised.
void MixUnchecked(std::span<const double> a, std::span<const double> b, double alpha,
                  std::span<double> out);

/// Euclidean projection onto V (sort-based, O(n log n); seed 001 §10.1 option C): the closest
/// valid distribution to `a`. Non-finite entries are treated as 0; an all-zero input gives the
/// uniform distribution.
Fractions ProjectToSimplex(std::span<const double> a);

/// A distribution with 1 for material `index` and 0 elsewhere (`materials` entries).
Fractions PureMaterial(int index, int materials);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_MATERIAL_H_
