/// @brief What voxelising a composite model into a level set needs beyond the inverse map (seed
/// 001 §10.3 steps 1-4): the external faces (7.7), a closed, outward-oriented triangle mesh of
/// them, and the volume of each material by quadrature, to check conservation after voxelising.
#ifndef SCULPT_HETERO_BOUNDARY_H_
#define SCULPT_HETERO_BOUNDARY_H_

#include <array>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"

namespace sculpt::hetero {

/// The faces that belong to exactly one cell (7.7): a face is internal when another cell has a
/// face at the same 16 positions (geometric identity, so a material discontinuity does not open
/// the boundary). Ascending (cell, axis, side).
std::vector<Face> ExternalFaces(const CompositeModel& model);

/// An indexed triangle mesh; triangles wind counter-clockwise seen from outside.
struct BoundaryMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  /// Edges used by other than exactly two triangles (0 for a closed mesh).
  size_t open_edges = 0;
  /// Enclosed volume by the divergence theorem.
  double Volume() const;
};

/// Tessellates every external face on an n×n grid of (u,v) squares (n in [1, 64]), welding
/// vertices shared between faces, oriented away from each cell's interior. InvalidArgument for a
/// bad n. open_edges reports cracks (faces shared only at some corners, §10.3 step 4).
StatusOr<BoundaryMesh> ExternalBoundaryMesh(const CompositeModel& model, int n);

/// Writes the mesh as Wavefront OBJ (what Sculpture::FromMeshFile reads).
Status WriteObj(const BoundaryMesh& mesh, const std::string& path);

/// ∫ |det J| and ∫ A_m |det J| over every cell by 6-point Gauss–Legendre per axis (exact for the
/// polynomial degrees of a tricubic cell).
struct MaterialVolumes {
  double total = 0;
  std::vector<double> per_material;
};
MaterialVolumes IntegrateVolumes(const CompositeModel& model);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_BOUNDARY_H_
