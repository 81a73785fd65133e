/// @brief Conversions between TriangleMesh and draco::Mesh, shared by the chunk codec and the
/// GLB writer. Internal: includes Draco.
#ifndef SCULPT_MESH_DRACO_MESH_H_
#define SCULPT_MESH_DRACO_MESH_H_

#include <draco/mesh/mesh.h>

#include <memory>

#include "sculpt/core/status.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh::internal {

/// A draco::Mesh with one float xyz POSITION attribute (identity mapping) and the mesh's faces.
/// InvalidArgument for an index past the vertices or a length not a multiple of 3.
StatusOr<std::unique_ptr<draco::Mesh>> ToDracoMesh(const TriangleMesh& mesh);

/// Positions (dequantised to floats) and faces of a decoded draco::Mesh. InvalidArgument when it
/// has no 3-component POSITION attribute.
StatusOr<TriangleMesh> FromDracoMesh(const draco::Mesh& mesh);

}  // namespace sculpt::mesh::internal

#endif  // SCULPT_MESH_DRACO_MESH_H_
