/// @brief Packed stroke poses and stroke validation into kernel edits.
#include "sculpt/codec/stroke.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sculpt/core/concat.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

constexpr int32_t kMaxPoseUnits = 32767;
constexpr uint32_t kMaxPoseMillis = 65535;
constexpr size_t kMaxObjectNameBytes = 64;
/// dt of a stroke's first pose (no previous sample): one frame at the fastest stroke rate.
constexpr double kFirstPoseDt = 1.0 / 120.0;
/// Two samples with the same timestamp still advance the press by this much.
constexpr double kMinPoseDt = 0.001;

/// Shortest text that reads back as the same value; `nan`/`inf` spelled plainly.
template <typename T>
std::string Num(T v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::array<char, 64> buf{};
  const auto result = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), result.ptr);
}

std::string Range(double lo, double hi) { return Concat({"[", Num(lo), ", ", Num(hi), "]"}); }

std::string Range(uint32_t lo, uint32_t hi) {
  return Concat({"[", std::to_string(lo), ", ", std::to_string(hi), "]"});
}

std::string Triple(double x, double y, double z) {
  return Concat({"(", Num(x), ", ", Num(y), ", ", Num(z), ")"});
}

/// A wire float: finite and in [lo, hi]. Printed as a float so `0.1` reads `0.1`, not the
/// double expansion of the float nearest to it.
Status CheckWireFloat(const std::string& field, float v, double lo, double hi) {
  if (!std::isfinite(v)) return NotFinite(field, Num(v));
  if (!(v >= lo && v <= hi)) return Outside(field, Num(v), Range(lo, hi));
  return Status::Ok();
}

Status CheckWireFinite(const std::string& field, float v) {
  if (std::isfinite(v)) return Status::Ok();
  return NotFinite(field, Num(v));
}

Status CheckVoxelSize(double voxel_size) {
  // A configuration error, not a client's: still a Status, because a zero voxel size would turn
  // every offset into inf or nan.
  if (std::isfinite(voxel_size) && voxel_size > 0) return Status::Ok();
  return Outside("voxel_size", Num(voxel_size), "(0, inf)");
}

/// The origin travels as float (Stroke.origin is a Vec3f): both ends quantise against the
/// float-rounded origin, or a client packing against a double origin would be off by the
/// rounding of every coordinate.
Vec3 WireOrigin(const Vec3& origin) {
  return {static_cast<float>(origin.x), static_cast<float>(origin.y), static_cast<float>(origin.z)};
}

void PutLittleEndian16(uint16_t v, std::string* out) {
  out->push_back(static_cast<char>(v & 0xff));
  out->push_back(static_cast<char>(v >> 8));
}

uint16_t GetLittleEndian16(const char* p) {
  // Through unsigned char: a plain char is signed here and would sign-extend bytes >= 0x80.
  const auto* u = reinterpret_cast<const unsigned char*>(p);
  return static_cast<uint16_t>(u[0] | (u[1] << 8));
}

// The wire enums are open (proto3): any int32 may arrive, so every mapping has a default.
std::optional<levelset::EditKind> MapEditKind(v1::EditKind kind) {
  switch (kind) {
    case v1::EDIT_KIND_PRESS:
      return levelset::EditKind::kPress;
    case v1::EDIT_KIND_ADD:
      return levelset::EditKind::kAdd;
    case v1::EDIT_KIND_SUBTRACT:
      return levelset::EditKind::kSubtract;
    case v1::EDIT_KIND_SMOOTH:
      return levelset::EditKind::kSmooth;
    case v1::EDIT_KIND_INFLATE:
      return levelset::EditKind::kInflate;
    case v1::EDIT_KIND_DEFLATE:
      return levelset::EditKind::kDeflate;
    default:
      return std::nullopt;
  }
}

std::optional<levelset::ToolKind> MapToolKind(v1::ToolKind tool) {
  switch (tool) {
    case v1::TOOL_KIND_SPHERE:
      return levelset::ToolKind::kSphere;
    case v1::TOOL_KIND_ELLIPSOID:
      return levelset::ToolKind::kEllipsoid;
    case v1::TOOL_KIND_BOX:
      return levelset::ToolKind::kBox;
    case v1::TOOL_KIND_CAPSULE:
      return levelset::ToolKind::kCapsule;
    default:
      return std::nullopt;
  }
}

bool UsesAmount(levelset::EditKind kind) {
  return kind == levelset::EditKind::kSmooth || kind == levelset::EditKind::kInflate ||
         kind == levelset::EditKind::kDeflate;
}

bool UsesRadiusOnly(levelset::ToolKind tool) {
  return tool == levelset::ToolKind::kSphere || tool == levelset::ToolKind::kCapsule;
}

Vec3 ToVec3(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

/// The tool of one pose. `previous` is the capsule's start (the pose itself for the first).
levelset::ToolShape MakeTool(levelset::ToolKind kind, const Vec3& size, const Vec3& previous,
                             const Vec3& position) {
  switch (kind) {
    case levelset::ToolKind::kSphere:
      return levelset::ToolShape::Sphere(position, size.x);
    case levelset::ToolKind::kEllipsoid:
      return levelset::ToolShape::Ellipsoid(position, size);
    case levelset::ToolKind::kBox:
      return levelset::ToolShape::Box(position, size);
    case levelset::ToolKind::kCapsule:
      return levelset::ToolShape::Capsule(previous, position, size.x);
  }
  // Unreachable for the four kinds; a value outside them keeps its kind so ValidateTool names
  // it rather than the edit silently becoming a sphere.
  levelset::ToolShape shape = levelset::ToolShape::Sphere(position, size.x);
  shape.kind = kind;
  return shape;
}

}  // namespace

StatusOr<std::string> PackPoses(const std::vector<Pose>& poses, const Vec3& origin,
                                double voxel_size) {
  SCULPT_RETURN_IF_ERROR(CheckVoxelSize(voxel_size));
  const Vec3 o = WireOrigin(origin);
  if (!o.IsFinite()) {
    return NotFinite("origin", Triple(origin.x, origin.y, origin.z));
  }
  const double units_per_world = kPoseUnitsPerVoxel / voxel_size;
  const double reach = kMaxPoseUnits / units_per_world;
  std::string out;
  out.reserve(poses.size() * kPackedPoseBytes);
  uint32_t previous_t = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose& pose = poses[i];
    const std::string name = Concat({"poses[", std::to_string(i), "]"});
    std::array<int16_t, 3> q{};
    for (int axis = 0; axis < 3; ++axis) {
      const std::string field = name + ".position." + "xyz"[axis];
      const double p = pose.position[axis];
      if (!std::isfinite(p)) return NotFinite(field, Num(p));
      const double units = (p - o[axis]) * units_per_world;
      // Checked before rounding, against the same bounds the message prints.
      if (!(units >= -kMaxPoseUnits && units <= kMaxPoseUnits)) {
        return Outside(field, Num(p), Range(o[axis] - reach, o[axis] + reach));
      }
      q[axis] = static_cast<int16_t>(std::lround(units));
    }
    if (pose.t_ms < previous_t || pose.t_ms > kMaxPoseMillis) {
      return Outside(name + ".t_ms", std::to_string(pose.t_ms), Range(previous_t, kMaxPoseMillis));
    }
    previous_t = pose.t_ms;
    for (int16_t v : q) PutLittleEndian16(static_cast<uint16_t>(v), &out);
    PutLittleEndian16(static_cast<uint16_t>(pose.t_ms), &out);
  }
  return out;
}

StatusOr<std::vector<Pose>> UnpackPoses(std::string_view bytes, uint32_t count, const Vec3& origin,
                                        double voxel_size, uint32_t max_count) {
  SCULPT_RETURN_IF_ERROR(CheckVoxelSize(voxel_size));
  if (count < 1 || count > max_count) {
    return Outside("Stroke.pose_count", std::to_string(count), Range(1u, max_count));
  }
  // count <= max_count (a uint32) and size_t is 64-bit: the product cannot overflow.
  const size_t expected = static_cast<size_t>(count) * kPackedPoseBytes;
  if (bytes.size() != expected) {
    const std::string exact = std::to_string(expected);
    return Outside("Stroke.poses", std::to_string(bytes.size()) + " bytes",
                   Concat({"[", exact, ", ", exact, "] bytes (pose_count ", std::to_string(count),
                        " x ", std::to_string(kPackedPoseBytes), ")"}));
  }
  const Vec3 o = WireOrigin(origin);
  const double world_per_unit = voxel_size / kPoseUnitsPerVoxel;
  std::vector<Pose> poses(count);
  uint32_t previous_t = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const char* p = bytes.data() + static_cast<size_t>(i) * kPackedPoseBytes;
    const auto qx = static_cast<int16_t>(GetLittleEndian16(p));
    const auto qy = static_cast<int16_t>(GetLittleEndian16(p + 2));
    const auto qz = static_cast<int16_t>(GetLittleEndian16(p + 4));
    const uint32_t t = GetLittleEndian16(p + 6);
    if (t < previous_t) {
      return Outside(Concat({"Stroke.poses[", std::to_string(i), "].t_ms"}), std::to_string(t),
                     Range(previous_t, kMaxPoseMillis));
    }
    previous_t = t;
    poses[i].position = {o.x + qx * world_per_unit, o.y + qy * world_per_unit,
                         o.z + qz * world_per_unit};
    poses[i].t_ms = t;
  }
  return poses;
}

StatusOr<DecodedStroke> DecodeStroke(const v1::Stroke& stroke, const StrokeLimits& limits) {
  const std::optional<levelset::EditKind> kind = MapEditKind(stroke.kind());
  if (!kind) {
    return Outside("Stroke.kind", std::to_string(static_cast<int>(stroke.kind())),
                   "[1, 6] (EDIT_KIND_PRESS..EDIT_KIND_DEFLATE)");
  }
  const std::optional<levelset::ToolKind> tool = MapToolKind(stroke.tool());
  if (!tool) {
    return Outside("Stroke.tool", std::to_string(static_cast<int>(stroke.tool())),
                   "[1, 4] (TOOL_KIND_SPHERE..TOOL_KIND_CAPSULE)");
  }
  // The length, not the name, goes into the message: it is untrusted and may be huge.
  if (stroke.object().empty() || stroke.object().size() > kMaxObjectNameBytes) {
    return Outside("Stroke.object", std::to_string(stroke.object().size()) + " bytes",
                   Concat({"[1, ", std::to_string(kMaxObjectNameBytes), "] bytes"}));
  }

  const v1::Vec3f& size = stroke.tool_size();
  SCULPT_RETURN_IF_ERROR(
      CheckWireFloat("Stroke.tool_size.x", size.x(), limits.min_tool_size, limits.max_tool_size));
  if (!UsesRadiusOnly(*tool)) {
    SCULPT_RETURN_IF_ERROR(
        CheckWireFloat("Stroke.tool_size.y", size.y(), limits.min_tool_size, limits.max_tool_size));
    SCULPT_RETURN_IF_ERROR(
        CheckWireFloat("Stroke.tool_size.z", size.z(), limits.min_tool_size, limits.max_tool_size));
  }
  SCULPT_RETURN_IF_ERROR(CheckWireFloat("Stroke.speed", stroke.speed(), 0, limits.max_speed));
  if (UsesAmount(*kind)) {
    SCULPT_RETURN_IF_ERROR(CheckWireFloat("Stroke.amount", stroke.amount(), 0, limits.max_amount));
  }
  const v1::Vec3f& origin = stroke.origin();
  SCULPT_RETURN_IF_ERROR(CheckWireFinite("Stroke.origin.x", origin.x()));
  SCULPT_RETURN_IF_ERROR(CheckWireFinite("Stroke.origin.y", origin.y()));
  SCULPT_RETURN_IF_ERROR(CheckWireFinite("Stroke.origin.z", origin.z()));

  SCULPT_ASSIGN_OR_RETURN(std::vector<Pose> poses,
                          UnpackPoses(stroke.poses(), stroke.pose_count(), ToVec3(origin),
                                      limits.voxel_size, limits.max_poses));

  const Vec3 margin{limits.bounds_margin, limits.bounds_margin, limits.bounds_margin};
  const Vec3 lo = limits.bounds.min - margin;
  const Vec3 hi = limits.bounds.max + margin;
  for (size_t i = 0; i < poses.size(); ++i) {
    const Vec3& p = poses[i].position;
    // Negated conjunctions, so a pose that overflowed to inf or nan is rejected too.
    if (!(p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z)) {
      return Outside(Concat({"Stroke.poses[", std::to_string(i), "]"}), Triple(p.x, p.y, p.z),
                     Concat({"[", Triple(lo.x, lo.y, lo.z), ", ", Triple(hi.x, hi.y, hi.z),
                          "] (object bounds grown by ", Num(limits.bounds_margin), ")"}));
    }
  }

  DecodedStroke out;
  out.client_seq = stroke.client_seq();
  out.object = stroke.object();
  out.edits.reserve(poses.size());
  const Vec3 tool_size = ToVec3(size);
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose& previous = poses[i == 0 ? 0 : i - 1];
    levelset::EditRequest edit;
    edit.kind = *kind;
    edit.tool = MakeTool(*tool, tool_size, previous.position, poses[i].position);
    edit.speed = stroke.speed();
    edit.dt =
        i == 0 ? kFirstPoseDt : std::max((poses[i].t_ms - previous.t_ms) / 1000.0, kMinPoseDt);
    // Only the kinds that use `amount` had it validated; the others carry 0 so that no
    // unchecked number (a nan, say) reaches the edit log.
    edit.amount = UsesAmount(*kind) ? stroke.amount() : 0.0;
    out.edits.push_back(edit);
  }
  out.poses = std::move(poses);
  out.source = stroke.SerializeAsString();
  return out;
}

StrokeLimits ReplicaLimits(double voxel_size) {
  StrokeLimits l;
  l.voxel_size = voxel_size;
  l.max_poses = 1u << 16;
  l.min_tool_size = 0;
  l.max_tool_size = 1e30;
  l.max_speed = 1e30;
  l.max_amount = 1e30;
  l.bounds = {{-1e30, -1e30, -1e30}, {1e30, 1e30, 1e30}};
  l.bounds_margin = 0;
  return l;
}

levelset::EditRequest EditFromRecord(const v1::EditRecord& record) {
  levelset::EditRequest edit;
  // A record with an enum outside the known values (a corrupt or newer log) keeps an invalid
  // kernel value instead of being mapped to a default, so ValidateEditRequest rejects the edit
  // by name rather than replaying a different one.
  constexpr auto kInvalidEditKind = static_cast<levelset::EditKind>(0xff);
  constexpr auto kInvalidToolKind = static_cast<levelset::ToolKind>(0xff);
  edit.kind = MapEditKind(record.kind()).value_or(kInvalidEditKind);
  const levelset::ToolKind tool = MapToolKind(record.tool()).value_or(kInvalidToolKind);
  edit.tool = MakeTool(tool, ToVec3(record.tool_size()), ToVec3(record.previous()),
                       ToVec3(record.position()));
  edit.speed = record.speed();
  edit.dt = record.dt();
  edit.amount = record.amount();
  return edit;
}

v1::Vec3f ToProto(const Vec3& v) {
  v1::Vec3f out;
  out.set_x(static_cast<float>(v.x));
  out.set_y(static_cast<float>(v.y));
  out.set_z(static_cast<float>(v.z));
  return out;
}

namespace {

v1::ToolKind ToolKindToProto(levelset::ToolKind k) {
  switch (k) {
    case levelset::ToolKind::kSphere: return v1::TOOL_KIND_SPHERE;
    case levelset::ToolKind::kEllipsoid: return v1::TOOL_KIND_ELLIPSOID;
    case levelset::ToolKind::kBox: return v1::TOOL_KIND_BOX;
    case levelset::ToolKind::kCapsule: return v1::TOOL_KIND_CAPSULE;
  }
  return v1::TOOL_KIND_UNSPECIFIED;
}

}  // namespace

v1::EditKind EditKindToProto(levelset::EditKind k) {
  switch (k) {
    case levelset::EditKind::kPress: return v1::EDIT_KIND_PRESS;
    case levelset::EditKind::kAdd: return v1::EDIT_KIND_ADD;
    case levelset::EditKind::kSubtract: return v1::EDIT_KIND_SUBTRACT;
    case levelset::EditKind::kSmooth: return v1::EDIT_KIND_SMOOTH;
    case levelset::EditKind::kInflate: return v1::EDIT_KIND_INFLATE;
    case levelset::EditKind::kDeflate: return v1::EDIT_KIND_DEFLATE;
  }
  return v1::EDIT_KIND_UNSPECIFIED;
}

v1::EditRecord RecordFromEdit(const levelset::EditRequest& e) {
  v1::EditRecord r;
  r.set_kind(EditKindToProto(e.kind));
  r.set_tool(ToolKindToProto(e.tool.kind));
  *r.mutable_tool_size() = ToProto(e.tool.size);
  if (e.tool.kind == levelset::ToolKind::kCapsule) {
    *r.mutable_previous() = ToProto(e.tool.center);
    *r.mutable_position() = ToProto(e.tool.end);
  } else {
    *r.mutable_position() = ToProto(e.tool.center);
  }
  r.set_speed(static_cast<float>(e.speed));
  r.set_dt(static_cast<float>(e.dt));
  r.set_amount(static_cast<float>(e.amount));
  return r;
}

}  // namespace sculpt::codec
