/// @brief Packed stroke poses (the compact wire form of proto/README.md) and the validation that
/// turns an untrusted sculpt.v1.Stroke into kernel edits, naming field, value and allowed range.
#ifndef SCULPT_CODEC_STROKE_H_
#define SCULPT_CODEC_STROKE_H_

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::v1 {
class Stroke;
class EditRecord;
class Vec3f;
enum EditKind : int;  // as protoc declares it, so the generated header stays out
}  // namespace sculpt::v1

namespace sculpt::codec {

/// One sampled tool pose: world position and milliseconds after the stroke's t0.
struct Pose {
  Vec3 position;
  uint32_t t_ms = 0;
};

/// Bytes per packed pose: int16 x, y, z offsets from the origin in 1/256 voxel, uint16 t_ms.
inline constexpr size_t kPackedPoseBytes = 8;
/// Offsets reach +-32767/256 voxels (about 128 voxels) from the stroke's origin.
inline constexpr double kPoseUnitsPerVoxel = 256.0;

/// Packs poses relative to `origin`. InvalidArgument if a pose is non-finite, farther than the
/// int16 range from the origin, or its t_ms exceeds 65535 or decreases.
StatusOr<std::string> PackPoses(const std::vector<Pose>& poses, const Vec3& origin,
                                double voxel_size);
/// Unpacks `count` poses. InvalidArgument (naming Stroke.pose_count or Stroke.poses) when the
/// byte length is not count * kPackedPoseBytes, count is 0 or above max_count, or timestamps
/// decrease.
StatusOr<std::vector<Pose>> UnpackPoses(std::string_view bytes, uint32_t count,
                                        const Vec3& origin, double voxel_size,
                                        uint32_t max_count);

/// Scene limits a stroke is checked against (world units unless noted).
struct StrokeLimits {
  double voxel_size = 1.0;
  uint32_t max_poses = 32;
  double min_tool_size = 0.5;
  double max_tool_size = 32.0;
  double max_speed = 1000.0;
  double max_amount = 16.0;
  /// The object's bounds; every pose must lie inside them grown by `bounds_margin`.
  levelset::Aabb bounds;
  double bounds_margin = 8.0;
};

/// A validated stroke: one kernel edit per pose, in order (a capsule tool sweeps from the
/// previous pose; the first pose of a capsule stroke sweeps from itself).
struct DecodedStroke {
  uint64_t client_seq = 0;
  std::string object;
  std::vector<levelset::EditRequest> edits;
  std::vector<Pose> poses;
  /// The validated wire message, serialized: replicas receive it (about 8 bytes a pose) and
  /// decode it into the same edits.
  std::string source;
};

/// Limits that accept any stroke the server accepted, for a replica decoding a broadcast stroke
/// (the server validated it; only the voxel size matters for unpacking).
StrokeLimits ReplicaLimits(double voxel_size);

/// Checks every field of an untrusted stroke and builds its edits. On failure returns
/// InvalidArgument carrying the field violation (Status::violation(): field, value, allowed range)
/// and the message `<field>=<value> outside <allowed range>` (e.g.
/// `Stroke.tool_size.x=-1 outside [0.5, 32]`) or `<field>=<value> is not finite`.
StatusOr<DecodedStroke> DecodeStroke(const v1::Stroke& stroke, const StrokeLimits& limits);

/// The kernel edit of a logged record (replay), and the record of an edit.
levelset::EditRequest EditFromRecord(const v1::EditRecord& record);
/// The inverse: the edit fields of a record (kind, tool, pose, speed, dt, amount; rounded to
/// float), leaving sequence numbers, client and object to the caller. Applying
/// EditFromRecord(RecordFromEdit(e)) is what the server and every replay do.
v1::EditRecord RecordFromEdit(const levelset::EditRequest& edit);
/// A world vector on the wire (float).
v1::Vec3f ToProto(const Vec3& v);
/// An edit kind on the wire.
v1::EditKind EditKindToProto(levelset::EditKind kind);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_STROKE_H_
