/// @brief WriteGlb: a sculpture's surface as a glTF 2.0 binary with KHR_draco_mesh_compression,
/// written by Draco's own glTF encoder.
#ifndef SCULPT_MESH_GLB_WRITER_H_
#define SCULPT_MESH_GLB_WRITER_H_

#include <string>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::mesh {

struct GlbOptions {
  /// Position quantisation bits in [1, 30].
  int position_bits = 14;
  /// Draco compression level in [0, 10] (10: smallest file).
  int compression_level = 7;
};

/// InvalidArgument naming the field, the value and the allowed range, else Ok.
Status ValidateGlbOptions(const GlbOptions& options);

/// Meshes the whole sculpture (MeshWhole) and writes it to `path` (which must end in .glb) as one
/// Draco-compressed mesh, with per-vertex COLOR_0 mixed from the material fractions when the
/// sculpture declares materials (ColourVertices). Returns the mesh's vertex and triangle counts. InvalidArgument for bad
/// options, another extension or an empty sculpture; Internal when Draco cannot write the file.
StatusOr<levelset::MeshStats> WriteGlb(const levelset::Sculpture& sculpture,
                                       const std::string& path, const GlbOptions& options = {});

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_GLB_WRITER_H_
