/// @brief Per-vertex display colours of a mesh mixed from a sculpture's material fractions
/// (issue 7): what viewers' Draco chunks and the GLB export carry as a COLOR attribute.
#ifndef SCULPT_MESH_VERTEX_COLOURS_H_
#define SCULPT_MESH_VERTEX_COLOURS_H_

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh {

/// Sets mesh->colours to levelset::ColourAtWorld at each vertex (sum_m a_m colour_m of the
/// trilinear fractions, each channel in [0, 1]); clears them when the sculpture declares no
/// materials. InvalidArgument for a non-finite vertex. A few microseconds per vertex.
Status ColourVertices(const levelset::Sculpture& sculpture, TriangleMesh* mesh);

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_VERTEX_COLOURS_H_
