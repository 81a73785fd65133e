/// @brief Building composite models (seed 001 §9): add a cell from the library or a file, extrude
/// a face along its normals, blend two faces; each new cell is checked for validity (and the
/// corners it shares are classified C1 or not) before it is accepted (§9.1).
#ifndef SCULPT_HETERO_CONSTRUCTION_H_
#define SCULPT_HETERO_CONSTRUCTION_H_

#include <array>
#include <span>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::hetero {

/// Where a new cell comes from (§9.2).
enum class CellSource { kLibrary, kFile, kExtrusion, kBlend, kUser };

/// A boundary surface of a cell: the slice with index `axis` fixed at 0 (side 0) or 3 (side 1).
struct Face {
  int cell = 0;
  int axis = 0;
  int side = 1;
};

/// The outcome of adding one cell.
struct AddCellResult {
  bool added = false;
  int cell = -1;
  Rejection rejection;                 // why not, when !added
  std::vector<uint32_t> c1_corners;    // shared corners classified C1 (geometry or material)
};

/// Adds a cell after the validity test (§9.1 step 1: the whole single-cell test, whatever the
/// source: the digest found the library shortcut unsound under rotation), overlap against the
/// existing cells, then classification of its shared corners (§9.1 step 2). Coefficients equal
/// in position and material to existing ones are shared (glued). A refused cell leaves the model
/// as it was. InvalidArgument when the patch itself is malformed.
StatusOr<AddCellResult> AddCellChecked(CompositeModel* model, ValidityChecker* checker,
                                       const Hyperpatch& patch, CellSource source);

/// Library cells (§9.2.3), parametrised by size and position; `a` is every coefficient's
/// distribution. InvalidArgument naming the parameter on bad input.
StatusOr<Hyperpatch> LibraryBox(const Vec3& min, const Vec3& max, std::span<const double> a);
/// A ring sector: radius r0..r1 along u, angle a0..a1 degrees along v (cubic arcs, at most 90°),
/// height z0..z1 along w, about the z axis.
StatusOr<Hyperpatch> LibraryRingSector(double r0, double r1, double a0_deg, double a1_deg,
                                       double z0, double z1, std::span<const double> a);

/// True when no other cell has a face at the same 16 positions (7.7). InvalidArgument on a bad
/// face.
StatusOr<bool> IsExternalFace(const CompositeModel& model, const Face& face);

/// Extrusion (§9.2.1): 3 new coefficients per surface coefficient along p_surface − p_interior at
/// cumulative distances `intervals`, copying the surface coefficient's material. The face must
/// be external; the new cell goes through AddCellChecked.
StatusOr<AddCellResult> Extrude(CompositeModel* model, ValidityChecker* checker, const Face& face,
                                std::array<double, 3> intervals);

/// Blending (§9.2.2) between two external faces of different cells: continuous places the 32 new
/// coefficients with (7.6) (2p* − p_interior), otherwise by linear interpolation at 1/3 and 2/3;
/// materials are copied from the associated surface coefficient. Face points correspond in the
/// order of each face's two free axes (the thesis keeps i, j, k consistent).
/// `flip_b` reverses B's first / second in-face index: the manual correspondence the thesis
/// offers when the two faces are parametrised in opposite senses.
StatusOr<AddCellResult> Blend(CompositeModel* model, ValidityChecker* checker, const Face& a,
                              const Face& b, bool continuous,
                              std::array<bool, 2> flip_b = {false, false});

/// De Casteljau subdivision of a cell into two at t along `axis` (Fig. 7.4), replacing it: the
/// first half keeps the index, the second is appended. Same geometry and materials.
/// InvalidArgument on a bad cell, axis or t.
Status SubdivideCell(CompositeModel* model, int cell, int axis, double t);

/// Index of control point (q along `axis`, (j, k) along the face's other two axes in order).
int FaceIndex(int axis, int q, int j, int k);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_CONSTRUCTION_H_
