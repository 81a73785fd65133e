/// @brief Material fractions in a Sculpture (issue 7, seed 001 §10.1 option C): n declared
/// materials, one fraction grid each beside the SDF, the paint brush (eq. 4.3), material volumes
/// and the simplex check. OpenVDB stays behind Sculpture::Impl.
#ifndef SCULPT_LEVELSET_MATERIALS_H_
#define SCULPT_LEVELSET_MATERIALS_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::levelset {

/// One declared material: a name and a display colour (linear RGB, each in [0, 1]).
struct MaterialDecl {
  std::string name;
  std::array<double, 3> colour{0.5, 0.5, 0.5};
  bool operator==(const MaterialDecl&) const = default;
};

// Edits carry fractions at their write-back (edit_block.cc's SpliceBack calls the carry rule on the
// block's before/after fields): every EditKind, batches, replays and ReinitializeRegion. The one
// exception is CompensationRegion::kGlobal, the thesis-reproduction mode that offsets the whole
// grid after the write-back: voxels its sub-voxel offset moves inside keep what they held.

/// Most materials a sculpture may declare (the hyperpatch library's bound, seed 001 §5).
inline constexpr int kMaxSculptureMaterials = 16;
/// How far a stored fraction vector's sum may stray from 1, and how negative an entry may be.
inline constexpr double kFractionTolerance = 1e-6;

/// InvalidArgument (field, value, range) for an empty or oversized list, an empty or over-long
/// name (64 bytes), a duplicate name, or a colour channel outside [0, 1].
Status ValidateMaterialDecls(const std::vector<MaterialDecl>& materials);

/// InvalidArgument naming `field`, the value and the range unless `a` holds `materials` finite
/// entries, each in [0, 1], summing to 1 within kFractionTolerance (seed 001 (4.2)). What every
/// API input carrying a fraction vector goes through (the wire included).
Status ValidateFractionVector(const std::string& field, std::span<const double> a, int materials);

/// Declares the sculpture's materials and gives every voxel, inside and out, the fractions
/// `fill` (empty: material 0 everywhere). One float grid per material whose background is its
/// fill value, so a uniform sculpture costs no voxels; values are stored only where they differ
/// (leaves, or tiles where a region is uniform). Declaring again replaces the materials and resets
/// every fraction. InvalidArgument for bad declarations or a bad `fill`; the sculpture is then
/// unchanged. Without a declaration the sculpture holds no fraction grids at all.
Status SetMaterials(Sculpture& sculpture, const std::vector<MaterialDecl>& materials,
                    std::span<const double> fill = {});

/// Number of declared materials (0 when none).
int MaterialCount(const Sculpture& sculpture);
/// The declared materials (empty when none).
const std::vector<MaterialDecl>& Materials(const Sculpture& sculpture);

/// The stored fractions of one voxel (index space). FailedPrecondition without materials.
StatusOr<std::vector<double>> FractionsAtVoxel(const Sculpture& sculpture, const Int3& voxel);
/// Trilinear fractions at a world point: a convex combination of valid vectors, so itself valid
/// (seed 001 §10.1). What a viewer mixes a vertex colour from. FailedPrecondition without
/// materials, InvalidArgument for a non-finite point.
StatusOr<std::vector<double>> FractionsAtWorld(const Sculpture& sculpture, const Vec3& p);
/// The display colour of the fractions at a world point: sum_m a_m colour_m.
StatusOr<std::array<double, 3>> ColourAtWorld(const Sculpture& sculpture, const Vec3& p);

/// What a material edit did.
struct MaterialEditResult {
  uint64_t changed_voxels = 0;
  /// Sorted origins of the leaf cells whose fractions changed.
  std::vector<Int3> dirty_leaves;
  double elapsed_ms = 0;
};

/// Largest paint tool, in voxels (a paint writes n values per voxel of the tool).
inline constexpr double kMaxPaintToolVoxels = 128;

/// The paint brush: inside the tool (its signed distance < 0), at every voxel inside the object
/// or within two voxels outside it, the fractions become
///   a <- e_material (+)_weight a = weight e_material + (1 - weight) a      (seed 001 eq. 4.3),
/// projected back onto the simplex (seed 001 §10.1). The SDF does not change. Deterministic.
/// FailedPrecondition without materials; InvalidArgument (field, value, range) for a bad tool
/// (size outside [0.5, kMaxPaintToolVoxels] voxels), material outside [0, n-1] or weight outside
/// [0, 1]. The sculpture is unchanged on error.
StatusOr<MaterialEditResult> PaintMaterial(Sculpture& sculpture, const ToolShape& tool,
                                           int material, double weight);

/// Sets the fractions of every voxel inside the tool (inside the object or within two voxels
/// of it) to `fractions` (a uniform material edit, seed 001 §8.2). Same errors as PaintMaterial,
/// and ValidateFractionVector's for `fractions`.
StatusOr<MaterialEditResult> FillMaterial(Sculpture& sculpture, const ToolShape& tool,
                                          std::span<const double> fractions);

/// Volume of each material (world units^3): sum over voxels of H_eps(phi) a_m dx^3 with the
/// smoothed Heaviside of Sculpture::volume() (seed 000 eq. 5.7), so the materials sum to
/// ComputeVolume() when every vector sums to 1. Walks the object once (not for the edit path).
/// Empty without materials.
std::vector<double> MaterialVolumes(const Sculpture& sculpture);

/// Every stored fraction vector (leaf voxels, tiles and the backgrounds of all grids).
struct SimplexReport {
  uint64_t vectors = 0;
  double max_sum_error = 0;  // max |sum - 1|
  double min_fraction = 0;   // smallest entry
  double max_fraction = 0;   // largest entry
  uint64_t non_finite = 0;
  bool Ok(double tol = kFractionTolerance) const {
    return non_finite == 0 && max_sum_error <= tol && min_fraction >= -tol &&
           max_fraction <= 1 + tol;
  }
};
SimplexReport CheckSimplex(const Sculpture& sculpture);

/// Bytes held by the fraction grids (0 without materials).
uint64_t MaterialMemoryBytes(const Sculpture& sculpture);

/// Hash of the fraction grids' contents (leaves in tree order, tiles, backgrounds); 0 without
/// materials. Equal on replicas that replayed the same edits.
uint64_t MaterialStateHash(const Sculpture& sculpture);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_MATERIALS_H_
