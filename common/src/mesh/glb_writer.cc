/// @brief WriteGlb: MeshWhole, then draco::GltfEncoder with Draco compression enabled on the
/// mesh (which makes the encoder emit KHR_draco_mesh_compression).
#include "sculpt/mesh/glb_writer.h"

#include <draco/compression/draco_compression_options.h>
#include <draco/io/gltf_encoder.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include "mesh/draco_mesh.h"
#include "sculpt/core/check.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/vertex_colours.h"

namespace sculpt::mesh {

Status ValidateGlbOptions(const GlbOptions& o) {
  SCULPT_RETURN_IF_ERROR(CheckRange("GlbOptions.position_bits", o.position_bits, 1, 30));
  return CheckRange("GlbOptions.compression_level", o.compression_level, 0, 10);
}

StatusOr<levelset::MeshStats> WriteGlb(const levelset::Sculpture& sculpture,
                                       const std::string& path, const GlbOptions& options) {
  SCULPT_RETURN_IF_ERROR(ValidateGlbOptions(options));
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  // Draco's encoder picks GLB or .gltf + .bin from the extension; only GLB is one file.
  if (ext != ".glb") return Outside("GLB path extension", ext, "{.glb}");
  TriangleMesh mesh = MeshWhole(sculpture);
  if (mesh.empty()) {
    return InvalidArgument("sculpture '" + sculpture.name() + "' has no surface to write");
  }
  // A sculpture with materials: COLOR_0 mixed from the fractions at each vertex.
  SCULPT_RETURN_IF_ERROR(ColourVertices(sculpture, &mesh));
  auto dm = internal::ToDracoMesh(mesh);
  if (!dm.ok()) return dm.status();
  draco::DracoCompressionOptions compression;
  compression.compression_level = options.compression_level;
  compression.quantization_position.SetQuantizationBits(options.position_bits);
  (*dm)->SetCompressionOptions(compression);
  (*dm)->SetCompressionEnabled(true);
  draco::GltfEncoder encoder;
  const draco::Status st = encoder.EncodeFile(**dm, path);
  if (!st.ok()) return Internal("GLB write to " + path + " failed: " + st.error_msg_string());
  return levelset::MeshStats{mesh.vertex_count(), mesh.face_count()};
}

}  // namespace sculpt::mesh
