/// @brief Sculpture::Impl and the dense-region helpers shared by the sculpture and its edits.
/// Internal: includes OpenVDB, so only .cc files of sculpt::levelset (and tests) include it.
#ifndef SCULPT_LEVELSET_SCULPTURE_IMPL_H_
#define SCULPT_LEVELSET_SCULPTURE_IMPL_H_

#include <openvdb/openvdb.h>

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

struct Sculpture::Impl {
  openvdb::FloatGrid::Ptr grid;
  std::string name;
  int half_width = 6;
  double volume = 0;
  double reference_volume = 0;
  uint64_t edits_since_reinit = 0;
  /// Conservative index bounds of the active voxels: exact at creation and load, grown by each
  /// edit's block, so reading it never walks the tree.
  openvdb::CoordBBox bounds;
  /// Declared materials and one fraction grid each (materials.h); both empty when the scene
  /// declares none, so a sculpture without materials pays nothing.
  std::vector<MaterialDecl> materials;
  std::vector<openvdb::FloatGrid::Ptr> fractions;

  double dx() const { return grid->voxelSize()[0]; }
  float background() const { return grid->background(); }
};

namespace internal {

/// Calls openvdb::initialize() once per process.
void EnsureOpenVdbInitialized();

/// An inclusive index-space box.
struct IndexBox {
  Int3 min, max;
  Int3 Dims() const { return {max.x - min.x + 1, max.y - min.y + 1, max.z - min.z + 1}; }
  bool Empty() const { return max.x < min.x || max.y < min.y || max.z < min.z; }
};

/// Index box covering the world box [lo, hi], dilated by `pad` voxels.
IndexBox WorldToIndexBox(const Vec3& lo, const Vec3& hi, double dx, int pad);

/// Copies phi over `box` out of the grid (tile and background values included).
DenseField ExtractDense(const openvdb::FloatGrid& grid, const IndexBox& box);

/// VolumeFraction (kernels.h) summed over a dense field of voxel size `dx`, in voxels; the
/// summation order is fixed, so the result is deterministic.
double DenseInsideSum(const DenseField& phi, double dx);

struct WriteBackResult {
  std::vector<Int3> dirty_leaves;  // sorted origins of leaves that changed
  uint64_t changed_voxels = 0;
};

/// Writes the voxels of `after` that differ from `before`, skipping a margin of `margin` voxels
/// at the box border (the stencil halo, which the edit only read). Values are clamped to the
/// band: |phi| < background stays active, the rest becomes an inactive +-background. Leaves left
/// uniform and inactive collapse into tiles, so equal states have equal trees. When `lo` and
/// `hi` are given, only the local index box [lo, hi) is visited: the caller knows that no voxel
/// outside it differs.
WriteBackResult WriteBack(openvdb::FloatGrid& grid, const DenseField& before,
                          const DenseField& after, int margin, const int* lo = nullptr,
                          const int* hi = nullptr);

/// Carries the material fractions through an SDF change over a block (materials.h; a no-op
/// without materials): every voxel of the block interior (`margin` from its border) whose phi
/// decreased from >= 0 to below two voxels takes a copy of the fractions of the material that
/// moved there, the nearest voxel inside the old surface along -grad phi. Copies, never
/// averages, so every vector stays in the simplex. Reads all sources before writing.
void CarryFractions(Sculpture::Impl& impl, const DenseField& before, const DenseField& after,
                    int margin);

/// The fraction grids stamped for a .vdb file (name, class, material index and colour).
openvdb::GridPtrVec MaterialGridsForFile(const Sculpture::Impl& impl);
/// Adopts the fraction grids found among a .vdb file's grids (none: no materials). DataLoss
/// naming the problem for missing indices, bad colours or a transform unlike the SDF's.
Status AdoptMaterialGrids(Sculpture::Impl& impl, const openvdb::GridPtrVec& grids);
/// Deep copies of the fraction grids (Clone).
void DeepCopyMaterials(Sculpture::Impl& impl);

}  // namespace internal
}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_SCULPTURE_IMPL_H_
