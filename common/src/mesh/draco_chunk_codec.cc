/// @brief Draco chunk codec: draco::Encoder with explicit position quantisation on a per-object
/// frame, and the matching decoder.
#include "sculpt/mesh/draco_chunk_codec.h"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>

#include <chrono>
#include <cmath>
#include <string>

#include "mesh/draco_mesh.h"
#include "sculpt/core/check.h"

namespace sculpt::mesh {
namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

StatusOr<QuantizationFrame> FrameAround(const levelset::Sculpture& sculpture, double pad_voxels) {
  SCULPT_RETURN_IF_ERROR(CheckRange("pad_voxels", pad_voxels, 0.0, 1e6));
  const levelset::Aabb b = sculpture.WorldBounds();
  if (b.min.x > b.max.x || b.min.y > b.max.y || b.min.z > b.max.z) {
    return InvalidArgument("sculpture '" + sculpture.name() + "' is empty: no frame around it");
  }
  const double pad = pad_voxels * sculpture.voxel_size();
  QuantizationFrame f;
  f.origin = b.min - Vec3{pad, pad, pad};
  f.range = std::max({b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z}) + 2 * pad;
  return f;
}

Status ValidateDracoChunkOptions(const DracoChunkOptions& o) {
  SCULPT_RETURN_IF_ERROR(CheckRange("DracoChunkOptions.position_bits", o.position_bits,
                                    kMinPositionBits, kMaxPositionBits));
  SCULPT_RETURN_IF_ERROR(CheckRange("DracoChunkOptions.speed", o.speed, 0, kMaxDracoSpeed));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("DracoChunkOptions.frame.origin", o.frame.origin));
  if (!(o.frame.range > 0)) {
    return Outside("DracoChunkOptions.frame.range", FormatNumber(o.frame.range),
                   std::string("(0, ") + FormatNumber(kMaxFrameRange) + "]");
  }
  return CheckRange("DracoChunkOptions.frame.range", o.frame.range, 0, kMaxFrameRange);
}

StatusOr<EncodedChunk> EncodeChunk(const TriangleMesh& mesh, const DracoChunkOptions& options) {
  SCULPT_RETURN_IF_ERROR(ValidateDracoChunkOptions(options));
  const auto t0 = std::chrono::steady_clock::now();
  EncodedChunk out;
  if (mesh.empty()) {
    out.encode_ms = MsSince(t0);
    return out;
  }
  // Draco does not clamp: a vertex outside the frame would wrap around in the quantised integers.
  const float origin[3] = {static_cast<float>(options.frame.origin.x),
                           static_cast<float>(options.frame.origin.y),
                           static_cast<float>(options.frame.origin.z)};
  const float range = static_cast<float>(options.frame.range);
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    for (int c = 0; c < 3; ++c) {
      const float p = mesh.positions[3 * v + c];
      if (!(p >= origin[c] && p <= origin[c] + range)) {
        return Outside(
            std::string("vertex ") + std::to_string(v) + " coordinate " + std::to_string(c),
            FormatNumber(p),
            std::string("the frame [") + FormatNumber(origin[c]) + ", " +
                FormatNumber(origin[c] + range) + "]");
      }
    }
  }
  auto dm = internal::ToDracoMesh(mesh);
  if (!dm.ok()) return dm.status();
  draco::Encoder encoder;
  encoder.SetSpeedOptions(options.speed, options.speed);
  encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION,
                                           options.position_bits, 3, origin, range);
  draco::EncoderBuffer buffer;
  const draco::Status st = encoder.EncodeMeshToBuffer(**dm, &buffer);
  if (!st.ok()) return Internal(std::string("Draco encode failed: ") + st.error_msg());
  out.bytes.assign(buffer.data(), buffer.size());
  out.vertices = static_cast<uint32_t>(mesh.vertex_count());
  out.faces = static_cast<uint32_t>(mesh.face_count());
  out.encode_ms = MsSince(t0);
  return out;
}

StatusOr<DecodedChunk> DecodeChunk(std::string_view bytes) {
  const auto t0 = std::chrono::steady_clock::now();
  DecodedChunk out;
  if (bytes.empty()) {
    out.decode_ms = MsSince(t0);
    return out;
  }
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  auto type = draco::Decoder::GetEncodedGeometryType(&buffer);
  if (!type.ok() || type.value() != draco::TRIANGULAR_MESH) {
    return InvalidArgument("chunk bytes (" + std::to_string(bytes.size()) +
                           " bytes) are not a Draco triangle mesh");
  }
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    return InvalidArgument(std::string("chunk bytes do not decode: ") +
                           decoded.status().error_msg());
  }
  auto mesh = internal::FromDracoMesh(*decoded.value());
  if (!mesh.ok()) return mesh.status();
  out.mesh = std::move(mesh).value();
  out.decode_ms = MsSince(t0);
  return out;
}

}  // namespace sculpt::mesh
