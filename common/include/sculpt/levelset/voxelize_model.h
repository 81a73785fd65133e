/// @brief Voxelising a composite heterogeneous hyperpatch model into a Sculpture (seed 001
/// §10.3): its closed boundary into the SDF as a CSG union (an add edit), its material
/// distribution into the fraction grids by inverting the hyperpatch map at voxel centres.
#ifndef SCULPT_LEVELSET_VOXELIZE_MODEL_H_
#define SCULPT_LEVELSET_VOXELIZE_MODEL_H_

#include <cstdint>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset {

struct VoxelizeOptions {
  /// Squares per external face edge in the boundary tessellation (hetero::ExternalBoundaryMesh,
  /// [1, 64]); the chord error should stay below about a quarter voxel (§10.3 step 2).
  int tessellation = 8;
};

struct VoxelizeResult {
  uint64_t boundary_triangles = 0;
  uint64_t sdf_changed_voxels = 0;
  /// Voxels that took the model's materials: located by the inverse map, or (near the boundary,
  /// where the tessellation and the exact cells differ, and outside it within two voxels) copied
  /// from the nearest located neighbour.
  uint64_t located_voxels = 0;
  uint64_t filled_voxels = 0;
  /// Voxels the model owns that neither could reach (they keep the fractions they held).
  uint64_t unreached_voxels = 0;
  double volume_added = 0;
  std::vector<Int3> dirty_leaves;
  double mesh_ms = 0;
  double sdf_ms = 0;
  double materials_ms = 0;
};

/// Unions the model's solid into the sculpture and writes its materials wherever the model is
/// the nearer surface. Declares the model's materials (names and colours) when the sculpture
/// has none. The reference volume grows by the volume added (an add edit moves it on purpose).
/// InvalidArgument when the sculpture declares another number of materials or the options are
/// bad; FailedPrecondition when the model's boundary is not closed (open edges: cracks between
/// partly shared faces, §10.3 step 4) or the model has no cells. The sculpture is unchanged on
/// error. Deterministic; cost follows the model's volume in voxels (a few µs per inside voxel).
StatusOr<VoxelizeResult> VoxelizeModel(Sculpture& sculpture, const hetero::CompositeModel& model,
                                       const VoxelizeOptions& options = {});

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_VOXELIZE_MODEL_H_
