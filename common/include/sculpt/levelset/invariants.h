/// @brief Checks of the invariants every edit keeps (issue 11): a valid narrow band around the
/// surface, |grad phi| near one where an edit wrote, no sub-voxel sheets or fibres. For tests and
/// diagnostics; the edit path calls only ThinMaterialThickness.
#ifndef SCULPT_LEVELSET_INVARIANTS_H_
#define SCULPT_LEVELSET_INVARIANTS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

/// The thickness (world units) of the material at an inside sample `v` (phi < 0) between two
/// outside samples `a` and `b` (phi >= 0) at `length` on either side: the larger of two
/// estimates, the crossings placed by linear interpolation and the values read as distances
/// (2 length - a - b). Infinity when v is not inside or a or b is not outside.
double ThinMaterialThickness(float v, float a, float b, double length);

/// Band checks over the voxels of some leaves (an edit's dirty leaves).
struct BandReport {
  uint64_t voxels = 0;            ///< voxels looked at
  uint64_t interface_voxels = 0;  ///< voxels with a 6-neighbour of the other sign
  /// Interface voxels with an inactive voxel (|phi| at the background) among their 26
  /// neighbours: the zero crossing within one voxel of the band's edge.
  uint64_t interface_near_band_edge = 0;
  /// Active voxels with |phi| below background - 1 voxel whose |grad phi| is outside
  /// [0.5, 1.5], |grad phi| measured as the largest difference quotient |phi(n) - phi(v)| / |n - v|
  /// over the 26 neighbours n: the slope of steepest descent, which an exact distance has equal
  /// to one within the lattice's angular resolution (at least 0.89) at kinks, corners and
  /// creases too, where one-sided first-order norms read anything from 0 to sqrt(3). Above 1.5
  /// is a cliff (the band torn where the interface left it); below 0.5 a flat (a band clamped
  /// or smeared).
  uint64_t gradient_checked = 0;
  uint64_t gradient_outside = 0;
  double worst_gradient = 1;  ///< the |grad phi| furthest from 1 among those checked
  Int3 worst_gradient_at{0, 0, 0};
  double min_gradient = 1, max_gradient = 1;
  /// Inside voxels (phi < 0) whose two opposite neighbours along some direction (an axis, a face
  /// diagonal or a body diagonal) are both outside with the material between them, placed by
  /// linear interpolation, thinner than one voxel (ThinMaterialThickness): a sheet or fibre the
  /// grid does not resolve.
  uint64_t thin_material = 0;
  Int3 thin_material_at{0, 0, 0};
  /// Outside voxels whose two neighbours along some axis are both inside: a crack one sample wide.
  uint64_t thin_gaps = 0;

  bool Ok() const {
    return interface_near_band_edge == 0 && gradient_outside == 0 && thin_material == 0;
  }
  std::string ToString() const;
};

/// Looks at every voxel of the given leaves (8-aligned origins), reading neighbours across them.
BandReport CheckBand(const Sculpture& sculpture, const std::vector<Int3>& leaf_origins);
/// Every leaf of the grid (a whole-grid pass, for tests).
BandReport CheckWholeBand(const Sculpture& sculpture);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_INVARIANTS_H_
