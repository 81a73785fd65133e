/// @brief Draco compression of chunk meshes on one quantisation grid per object, so that the
/// vertices two chunks share stay identical after quantisation.
#ifndef SCULPT_MESH_DRACO_CHUNK_CODEC_H_
#define SCULPT_MESH_DRACO_CHUNK_CODEC_H_

#include <cstdint>
#include <string>
#include <string_view>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::mesh {

/// The cube [origin, origin + range]^3 (world units) that positions are quantised in. Every chunk
/// of one object must use the same frame: Draco then maps a seam vertex to the same integers
/// whichever chunk carries it.
struct QuantizationFrame {
  Vec3 origin;
  double range = 1.0;
};

/// A frame for `sculpture`: the cube around its current world bounds grown by `pad_voxels` on
/// every side. Choose it once per object (a scene's bounds, or this at load time) and keep it:
/// recomputing it after edits moves the grid. InvalidArgument for an empty sculpture or a
/// negative or non-finite pad.
StatusOr<QuantizationFrame> FrameAround(const levelset::Sculpture& sculpture, double pad_voxels);

inline constexpr int kMinPositionBits = 1;
inline constexpr int kMaxPositionBits = 30;  // Draco's limit for attribute quantisation
inline constexpr int kMaxDracoSpeed = 10;
inline constexpr double kMaxFrameRange = 1e9;

struct DracoChunkOptions {
  /// Position quantisation bits in [1, 30]: the step is range / (2^bits - 1).
  int position_bits = 14;
  /// Draco encoding/decoding speed in [0, 10] (0: smallest output, 10: fastest).
  int speed = 5;
  QuantizationFrame frame;
};

/// InvalidArgument naming the field, the value and the allowed range, else Ok. These come from
/// the scene file.
Status ValidateDracoChunkOptions(const DracoChunkOptions& options);

struct EncodedChunk {
  /// Draco bitstream; empty for a mesh with no faces (a chunk whose surface went away).
  std::string bytes;
  uint32_t vertices = 0;
  uint32_t faces = 0;
  double encode_ms = 0;
};

/// Encodes with draco::Encoder (edgebreaker, explicit quantisation on options.frame); a mesh with
/// colours gets a COLOR attribute of 8 bits a channel (normalised unsigned bytes).
/// InvalidArgument for bad options, a mesh whose indices point past its vertices, or a vertex
/// outside the frame (naming it); Internal if Draco fails.
StatusOr<EncodedChunk> EncodeChunk(const TriangleMesh& mesh, const DracoChunkOptions& options);

struct DecodedChunk {
  /// Dequantised positions, colours (when the chunk has a COLOR attribute, clamped to [0, 1]) and
  /// faces as Draco decodes them (vertex order may differ from the encoded mesh).
  TriangleMesh mesh;
  double decode_ms = 0;
};

/// Decodes what EncodeChunk wrote; empty bytes decode to an empty mesh. InvalidArgument for bytes
/// that are not a Draco triangle mesh with float xyz positions (never crashes on bad input).
StatusOr<DecodedChunk> DecodeChunk(std::string_view bytes);

}  // namespace sculpt::mesh

#endif  // SCULPT_MESH_DRACO_CHUNK_CODEC_H_
