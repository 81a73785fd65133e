/// @brief Unit tests for packed poses, stroke validation into edits, and error-message parsing.
#include "sculpt/codec/stroke.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "sculpt/codec/frame.h"
#include "sculpt/levelset/tool.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

constexpr float kNanF = std::numeric_limits<float>::quiet_NaN();
constexpr float kInfF = std::numeric_limits<float>::infinity();

/// A 0.5-voxel scene with an object in [0, 40]^3; poses may reach 8 beyond it.
StrokeLimits Limits() {
  StrokeLimits limits;
  limits.voxel_size = 0.5;
  limits.max_poses = 32;
  limits.min_tool_size = 0.5;
  limits.max_tool_size = 32;
  limits.max_speed = 1000;
  limits.max_amount = 16;
  limits.bounds = {{0, 0, 0}, {40, 40, 40}};
  limits.bounds_margin = 8;
  return limits;
}

/// `count` poses along +x from (10, 20, 20), 1 world unit and 8 ms apart.
std::vector<Pose> LinePoses(int count) {
  std::vector<Pose> poses;
  for (int i = 0; i < count; ++i) {
    poses.push_back({Vec3{10.0 + i, 20, 20.0 + 0.01 * i}, static_cast<uint32_t>(8 * i)});
  }
  return poses;
}

/// A valid press stroke with a sphere tool of radius 2 over `poses`, packed from (16, 20, 20).
v1::Stroke MakeStroke(const std::vector<Pose>& poses) {
  v1::Stroke s;
  s.set_client_seq(7);
  s.set_object("clay");
  s.set_kind(v1::EDIT_KIND_PRESS);
  s.set_tool(v1::TOOL_KIND_SPHERE);
  s.mutable_tool_size()->set_x(2);
  s.set_speed(40);
  s.set_amount(0);
  s.mutable_origin()->set_x(16);
  s.mutable_origin()->set_y(20);
  s.mutable_origin()->set_z(20);
  s.set_t0_ms(123456789);
  s.set_pose_count(static_cast<uint32_t>(poses.size()));
  StatusOr<std::string> packed = PackPoses(poses, {16, 20, 20}, Limits().voxel_size);
  EXPECT_TRUE(packed.ok()) << packed.status();
  if (packed.ok()) s.set_poses(*packed);
  return s;
}

v1::Stroke MakeStroke() { return MakeStroke(LinePoses(4)); }

/// Expects an InvalidArgument whose message names `field` and `value` and whose violation holds
/// them and the allowed range.
void ExpectFieldError(const Status& status, const std::string& field, const std::string& value,
                      const std::string& allowed_range) {
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(status.message().find(field), std::string::npos) << status.message();
  EXPECT_NE(status.message().find(value), std::string::npos) << status.message();
  const Status::Violation* e = status.violation();
  ASSERT_NE(e, nullptr) << status;
  EXPECT_EQ(e->field, field) << status.message();
  EXPECT_EQ(e->value, value) << status.message();
  EXPECT_EQ(e->allowed_range, allowed_range) << status.message();
}

Status DecodeStatus(const v1::Stroke& stroke) { return DecodeStroke(stroke, Limits()).status(); }

// --- Packed poses ---------------------------------------------------------------------------

TEST(StrokeTest, PackUnpackRoundTripWithinHalfUnit) {
  const double voxel = 0.1;
  const Vec3 origin{1.25, -3.5, 7};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> offset(-12.7, 12.7);  // reach is 32767/256 * 0.1
  std::vector<Pose> poses;
  for (uint32_t i = 0; i < 32; ++i) {
    poses.push_back({origin + Vec3{offset(rng), offset(rng), offset(rng)}, i * 9});
  }
  StatusOr<std::string> packed = PackPoses(poses, origin, voxel);
  ASSERT_TRUE(packed.ok()) << packed.status();
  ASSERT_EQ(packed->size(), poses.size() * kPackedPoseBytes);
  StatusOr<std::vector<Pose>> unpacked = UnpackPoses(*packed, 32, origin, voxel, 32);
  ASSERT_TRUE(unpacked.ok()) << unpacked.status();
  const double tolerance = voxel / (2 * kPoseUnitsPerVoxel) * (1 + 1e-9);  // 1/512 voxel
  double worst = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    for (int axis = 0; axis < 3; ++axis) {
      worst = std::max(worst, std::fabs((*unpacked)[i].position[axis] - poses[i].position[axis]));
    }
    EXPECT_EQ((*unpacked)[i].t_ms, poses[i].t_ms);
  }
  EXPECT_LE(worst, tolerance);
}

TEST(StrokeTest, PackedPoseIsLittleEndianInt16OffsetsThenUint16Time) {
  // x = +1 voxel = 256 units, y = -1 unit, z = 0, t = 0x0102 ms.
  const std::vector<Pose> poses{{Vec3{1, -1.0 / 256, 0}, 0x0102}};
  StatusOr<std::string> packed = PackPoses(poses, {0, 0, 0}, 1.0);
  ASSERT_TRUE(packed.ok()) << packed.status();
  EXPECT_EQ(*packed, std::string("\x00\x01\xff\xff\x00\x00\x02\x01", 8));
}

TEST(StrokeTest, PackRejectsPoseBeyondInt16Reach) {
  const std::vector<Pose> poses{{Vec3{0, 0, 200}, 0}};
  ExpectFieldError(PackPoses(poses, {0, 0, 0}, 1.0).status(), "poses[0].position.z", "200",
                   "[-127.99609375, 127.99609375]");
}

TEST(StrokeTest, PackRejectsNanPose) {
  const std::vector<Pose> poses{{Vec3{0, std::nan(""), 0}, 0}};
  ExpectFieldError(PackPoses(poses, {0, 0, 0}, 1.0).status(), "poses[0].position.y", "nan",
                   "finite numbers");
}

TEST(StrokeTest, PackRejectsDecreasingTime) {
  const std::vector<Pose> poses{{Vec3{}, 10}, {Vec3{}, 9}};
  ExpectFieldError(PackPoses(poses, {0, 0, 0}, 1.0).status(), "poses[1].t_ms", "9", "[10, 65535]");
}

TEST(StrokeTest, PackRejectsTimeAboveUint16) {
  const std::vector<Pose> poses{{Vec3{}, 65536}};
  ExpectFieldError(PackPoses(poses, {0, 0, 0}, 1.0).status(), "poses[0].t_ms", "65536",
                   "[0, 65535]");
}

// --- DecodeStroke: valid strokes -------------------------------------------------------------

TEST(StrokeTest, DecodesSphereStrokeCentredAtEachPose) {
  const std::vector<Pose> poses = LinePoses(4);
  StatusOr<DecodedStroke> decoded = DecodeStroke(MakeStroke(poses), Limits());
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->client_seq, 7u);
  EXPECT_EQ(decoded->object, "clay");
  ASSERT_EQ(decoded->edits.size(), 4u);
  ASSERT_EQ(decoded->poses.size(), 4u);
  const double tolerance = Limits().voxel_size / 512 * (1 + 1e-9);
  for (size_t i = 0; i < 4; ++i) {
    const levelset::EditRequest& e = decoded->edits[i];
    EXPECT_EQ(e.kind, levelset::EditKind::kPress);
    EXPECT_EQ(e.tool.kind, levelset::ToolKind::kSphere);
    EXPECT_DOUBLE_EQ(e.tool.size.x, 2);
    EXPECT_NEAR(e.tool.center.x, poses[i].position.x, tolerance);
    EXPECT_NEAR(e.tool.center.y, poses[i].position.y, tolerance);
    EXPECT_NEAR(e.tool.center.z, poses[i].position.z, tolerance);
    EXPECT_EQ(e.tool.center, decoded->poses[i].position);
    EXPECT_DOUBLE_EQ(e.speed, 40);
    // The first pose has no predecessor: one 120 Hz frame; the rest: 8 ms apart.
    EXPECT_DOUBLE_EQ(e.dt, i == 0 ? 1.0 / 120 : 0.008);
    EXPECT_TRUE(levelset::ValidateTool(e.tool, 0.5, 32).ok());
  }
}

TEST(StrokeTest, ValidCapsuleStrokeChainsPoseToPose) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_tool(v1::TOOL_KIND_CAPSULE);
  StatusOr<DecodedStroke> decoded = DecodeStroke(stroke, Limits());
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  ASSERT_EQ(decoded->edits.size(), 4u);
  const std::vector<levelset::EditRequest>& edits = decoded->edits;
  EXPECT_EQ(edits[0].tool.kind, levelset::ToolKind::kCapsule);
  EXPECT_EQ(edits[0].tool.center, decoded->poses[0].position);
  EXPECT_EQ(edits[0].tool.end, decoded->poses[0].position);
  for (size_t i = 1; i < edits.size(); ++i) {
    EXPECT_EQ(edits[i].tool.kind, levelset::ToolKind::kCapsule);
    EXPECT_EQ(edits[i].tool.center, edits[i - 1].tool.end) << i;
    EXPECT_EQ(edits[i].tool.end, decoded->poses[i].position) << i;
    EXPECT_DOUBLE_EQ(edits[i].tool.size.x, 2);
  }
}

TEST(StrokeTest, EqualTimestampsGetOneMillisecondDt) {
  std::vector<Pose> poses = LinePoses(3);
  poses[1].t_ms = poses[2].t_ms = 5;
  StatusOr<DecodedStroke> decoded = DecodeStroke(MakeStroke(poses), Limits());
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_DOUBLE_EQ(decoded->edits[1].dt, 0.005);
  EXPECT_DOUBLE_EQ(decoded->edits[2].dt, 0.001);
}

TEST(StrokeTest, MapsEveryKindAndTool) {
  const std::vector<std::pair<v1::EditKind, levelset::EditKind>> kinds{
      {v1::EDIT_KIND_PRESS, levelset::EditKind::kPress},
      {v1::EDIT_KIND_ADD, levelset::EditKind::kAdd},
      {v1::EDIT_KIND_SUBTRACT, levelset::EditKind::kSubtract},
      {v1::EDIT_KIND_SMOOTH, levelset::EditKind::kSmooth},
      {v1::EDIT_KIND_INFLATE, levelset::EditKind::kInflate},
      {v1::EDIT_KIND_DEFLATE, levelset::EditKind::kDeflate}};
  const std::vector<std::pair<v1::ToolKind, levelset::ToolKind>> tools{
      {v1::TOOL_KIND_SPHERE, levelset::ToolKind::kSphere},
      {v1::TOOL_KIND_ELLIPSOID, levelset::ToolKind::kEllipsoid},
      {v1::TOOL_KIND_BOX, levelset::ToolKind::kBox},
      {v1::TOOL_KIND_CAPSULE, levelset::ToolKind::kCapsule}};
  for (const auto& [wire_kind, kind] : kinds) {
    for (const auto& [wire_tool, tool] : tools) {
      v1::Stroke stroke = MakeStroke();
      stroke.set_kind(wire_kind);
      stroke.set_tool(wire_tool);
      stroke.mutable_tool_size()->set_y(3);
      stroke.mutable_tool_size()->set_z(4);
      stroke.set_amount(1.5);
      StatusOr<DecodedStroke> decoded = DecodeStroke(stroke, Limits());
      ASSERT_TRUE(decoded.ok()) << decoded.status();
      const levelset::EditRequest& e = decoded->edits.back();
      EXPECT_EQ(e.kind, kind);
      EXPECT_EQ(e.tool.kind, tool);
      const bool uses_amount = kind == levelset::EditKind::kSmooth ||
                               kind == levelset::EditKind::kInflate ||
                               kind == levelset::EditKind::kDeflate;
      EXPECT_DOUBLE_EQ(e.amount, uses_amount ? 1.5 : 0.0);
      if (tool == levelset::ToolKind::kEllipsoid || tool == levelset::ToolKind::kBox) {
        EXPECT_EQ(e.tool.size, (Vec3{2, 3, 4}));
      } else {
        EXPECT_DOUBLE_EQ(e.tool.size.x, 2);
      }
    }
  }
}

TEST(StrokeTest, SphereIgnoresUnusedToolSizeComponents) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_tool_size()->set_y(kNanF);
  stroke.mutable_tool_size()->set_z(-5);
  StatusOr<DecodedStroke> decoded = DecodeStroke(stroke, Limits());
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_TRUE(decoded->edits[0].tool.size.IsFinite());
}

// --- DecodeStroke: rejections ----------------------------------------------------------------

TEST(StrokeTest, RejectsNanToolPose) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_origin()->set_y(kNanF);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.origin.y", "nan", "finite numbers");
}

TEST(StrokeTest, RejectsInfiniteSpeed) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_speed(kInfF);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.speed", "inf", "finite numbers");
}

TEST(StrokeTest, RejectsNegativeSpeed) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_speed(-1);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.speed", "-1", "[0, 1000]");
}

TEST(StrokeTest, RejectsNegativeToolSize) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_tool_size()->set_x(-1);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool_size.x", "-1", "[0.5, 32]");
  EXPECT_EQ(DecodeStatus(stroke).message(), "Stroke.tool_size.x=-1 outside [0.5, 32]");
}

TEST(StrokeTest, RejectsToolSizeAboveMax) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_tool_size()->set_x(32.5);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool_size.x", "32.5", "[0.5, 32]");
}

TEST(StrokeTest, RejectsNanToolSize) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_tool_size()->set_x(kNanF);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool_size.x", "nan", "finite numbers");
}

TEST(StrokeTest, RejectsEllipsoidSemiAxisBelowMin) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_tool(v1::TOOL_KIND_ELLIPSOID);
  stroke.mutable_tool_size()->set_y(3);
  stroke.mutable_tool_size()->set_z(0.25);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool_size.z", "0.25", "[0.5, 32]");
}

TEST(StrokeTest, RejectsUnknownEditKind) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_kind(static_cast<v1::EditKind>(99));
  ExpectFieldError(DecodeStatus(stroke), "Stroke.kind", "99",
                   "[1, 6] (EDIT_KIND_PRESS..EDIT_KIND_DEFLATE)");
}

TEST(StrokeTest, RejectsUnspecifiedEditKind) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_kind(v1::EDIT_KIND_UNSPECIFIED);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.kind", "0",
                   "[1, 6] (EDIT_KIND_PRESS..EDIT_KIND_DEFLATE)");
}

TEST(StrokeTest, RejectsUnspecifiedTool) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_tool(v1::TOOL_KIND_UNSPECIFIED);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool", "0",
                   "[1, 4] (TOOL_KIND_SPHERE..TOOL_KIND_CAPSULE)");
}

TEST(StrokeTest, RejectsUnknownToolKind) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_tool(static_cast<v1::ToolKind>(-3));
  ExpectFieldError(DecodeStatus(stroke), "Stroke.tool", "-3",
                   "[1, 4] (TOOL_KIND_SPHERE..TOOL_KIND_CAPSULE)");
}

TEST(StrokeTest, RejectsEmptyObjectName) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_object("");
  ExpectFieldError(DecodeStatus(stroke), "Stroke.object", "0 bytes", "[1, 64] bytes");
}

TEST(StrokeTest, RejectsObjectNameTooLong) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_object(std::string(65, 'o'));
  ExpectFieldError(DecodeStatus(stroke), "Stroke.object", "65 bytes", "[1, 64] bytes");
  stroke.set_object(std::string(64, 'o'));
  EXPECT_TRUE(DecodeStatus(stroke).ok());
}

TEST(StrokeTest, RejectsAmountAboveMax) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_kind(v1::EDIT_KIND_INFLATE);
  stroke.set_amount(17);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.amount", "17", "[0, 16]");
}

TEST(StrokeTest, RejectsNanAmountForSmooth) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_kind(v1::EDIT_KIND_SMOOTH);
  stroke.set_amount(kNanF);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.amount", "nan", "finite numbers");
}

TEST(StrokeTest, RejectsPoseCountMismatch) {
  v1::Stroke stroke = MakeStroke();  // 4 poses
  stroke.mutable_poses()->resize(3 * kPackedPoseBytes);
  ExpectFieldError(DecodeStatus(stroke), "Stroke.poses", "24 bytes",
                   "[32, 32] bytes (pose_count 4 x 8)");
  stroke = MakeStroke();
  stroke.mutable_poses()->push_back('\0');  // one byte too many
  ExpectFieldError(DecodeStatus(stroke), "Stroke.poses", "33 bytes",
                   "[32, 32] bytes (pose_count 4 x 8)");
}

TEST(StrokeTest, RejectsTooManyPoses) {
  const v1::Stroke stroke = MakeStroke(LinePoses(33));
  ExpectFieldError(DecodeStatus(stroke), "Stroke.pose_count", "33", "[1, 32]");
  EXPECT_TRUE(DecodeStatus(MakeStroke(LinePoses(32))).ok());
}

TEST(StrokeTest, RejectsZeroPoses) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_pose_count(0);
  stroke.clear_poses();
  ExpectFieldError(DecodeStatus(stroke), "Stroke.pose_count", "0", "[1, 32]");
}

TEST(StrokeTest, RejectsDecreasingTimestamps) {
  v1::Stroke stroke = MakeStroke();  // t = 0, 8, 16, 24 ms
  // Pose 2's timestamp (bytes 6..7 of its record) becomes 3 ms, before pose 1's 8 ms.
  std::string* bytes = stroke.mutable_poses();
  (*bytes)[2 * kPackedPoseBytes + 6] = 3;
  (*bytes)[2 * kPackedPoseBytes + 7] = 0;
  ExpectFieldError(DecodeStatus(stroke), "Stroke.poses[2].t_ms", "3", "[8, 65535]");
}

TEST(StrokeTest, RejectsPoseOutsideBounds) {
  // Bounds [0, 40]^3 grown by 8: a pose at x = 49 is out, at 48 in.
  std::vector<Pose> poses = LinePoses(2);
  poses[1].position = {49, 20, 20};
  ExpectFieldError(DecodeStatus(MakeStroke(poses)), "Stroke.poses[1]", "(49, 20, 20)",
                   "[(-8, -8, -8), (48, 48, 48)] (object bounds grown by 8)");
  poses[1].position = {48, 20, 20};
  EXPECT_TRUE(DecodeStatus(MakeStroke(poses)).ok());
}

TEST(StrokeTest, RejectsHugeOriginAsPoseOutsideBounds) {
  v1::Stroke stroke = MakeStroke();
  stroke.mutable_origin()->set_x(3e38f);
  const Status status = DecodeStatus(stroke);
  ASSERT_FALSE(status.ok());
  ASSERT_NE(status.violation(), nullptr) << status;
  EXPECT_EQ(status.violation()->field, "Stroke.poses[0]");
}

// --- Field violations of the kernel's validators ------------------------------------------------

TEST(StrokeTest, KernelValidatorCarriesFieldViolation) {
  // The kernel's own validator, not a hand-written copy of its format.
  const Status kernel =
      levelset::ValidateTool(levelset::ToolShape::Sphere({0, 0, 0}, 100), 0.5, 64);
  ASSERT_NE(kernel.violation(), nullptr) << kernel;
  EXPECT_EQ(kernel.violation()->field, "tool.size.x");
  EXPECT_EQ(kernel.violation()->value, "100");
  EXPECT_EQ(kernel.violation()->allowed_range, "[0.5, 64]");
  EXPECT_EQ(kernel.message(), "tool.size.x=100 outside [0.5, 64]");

  const Status nan = levelset::ValidateTool(
      levelset::ToolShape::Sphere({0, std::numeric_limits<double>::quiet_NaN(), 0}, 1), 0.5, 64);
  ASSERT_NE(nan.violation(), nullptr) << nan;
  EXPECT_EQ(nan.violation()->field, "tool.center.y");
  EXPECT_EQ(nan.violation()->value, "nan");
  EXPECT_EQ(nan.violation()->allowed_range, "finite numbers");
  EXPECT_EQ(nan.message(), "tool.center.y=nan is not finite");
}

// --- EditFromRecord ----------------------------------------------------------------------------

TEST(StrokeTest, EditFromRecordBuildsCapsuleFromPrevious) {
  v1::EditRecord record;
  record.set_kind(v1::EDIT_KIND_DEFLATE);
  record.set_tool(v1::TOOL_KIND_CAPSULE);
  record.mutable_tool_size()->set_x(1.5);
  record.mutable_previous()->set_x(1);
  record.mutable_position()->set_x(2);
  record.mutable_position()->set_z(-4);
  record.set_speed(10);
  record.set_dt(0.25);
  record.set_amount(0.75);
  const levelset::EditRequest e = EditFromRecord(record);
  EXPECT_EQ(e.kind, levelset::EditKind::kDeflate);
  EXPECT_EQ(e.tool.kind, levelset::ToolKind::kCapsule);
  EXPECT_EQ(e.tool.center, (Vec3{1, 0, 0}));
  EXPECT_EQ(e.tool.end, (Vec3{2, 0, -4}));
  EXPECT_DOUBLE_EQ(e.tool.size.x, 1.5);
  EXPECT_DOUBLE_EQ(e.speed, 10);
  EXPECT_DOUBLE_EQ(e.dt, 0.25);
  EXPECT_DOUBLE_EQ(e.amount, 0.75);
}

TEST(StrokeTest, EditFromRecordMatchesDecodedStroke) {
  v1::Stroke stroke = MakeStroke();
  stroke.set_kind(v1::EDIT_KIND_ADD);
  stroke.set_tool(v1::TOOL_KIND_BOX);
  stroke.mutable_tool_size()->set_y(1);
  stroke.mutable_tool_size()->set_z(3);
  StatusOr<DecodedStroke> decoded = DecodeStroke(stroke, Limits());
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  const levelset::EditRequest& want = decoded->edits[2];
  v1::EditRecord record;
  record.set_kind(v1::EDIT_KIND_ADD);
  record.set_tool(v1::TOOL_KIND_BOX);
  *record.mutable_tool_size() = stroke.tool_size();
  record.mutable_position()->set_x(static_cast<float>(want.tool.center.x));
  record.mutable_position()->set_y(static_cast<float>(want.tool.center.y));
  record.mutable_position()->set_z(static_cast<float>(want.tool.center.z));
  record.set_speed(stroke.speed());
  record.set_dt(static_cast<float>(want.dt));
  const levelset::EditRequest got = EditFromRecord(record);
  EXPECT_EQ(got.kind, want.kind);
  EXPECT_EQ(got.tool.kind, want.tool.kind);
  EXPECT_EQ(got.tool.size, want.tool.size);
  EXPECT_NEAR(got.tool.center.x, want.tool.center.x, 1e-5);
  EXPECT_NEAR(got.tool.center.z, want.tool.center.z, 1e-5);
  EXPECT_FLOAT_EQ(got.dt, want.dt);
}

TEST(StrokeTest, EditFromRecordKeepsUnknownKindInvalid) {
  v1::EditRecord record;
  record.set_kind(static_cast<v1::EditKind>(42));
  record.set_tool(static_cast<v1::ToolKind>(42));
  record.mutable_tool_size()->set_x(1);
  const levelset::EditRequest e = EditFromRecord(record);
  // Neither becomes a press nor a sphere: the kernel's validation rejects it by name.
  EXPECT_GT(static_cast<int>(e.kind), static_cast<int>(levelset::EditKind::kDeflate));
  const Status tool_status = levelset::ValidateTool(e.tool, 0.5, 64);
  ASSERT_FALSE(tool_status.ok());
  ASSERT_NE(tool_status.violation(), nullptr) << tool_status;
  EXPECT_EQ(tool_status.violation()->field, "tool.kind");
}

// --- Size on the wire --------------------------------------------------------------------------

TEST(StrokeTest, BytesPerPoseSampleBelowNaiveMessage) {
  v1::ClientMessage message;
  *message.mutable_stroke() = MakeStroke(LinePoses(4));
  std::string framed;
  ASSERT_TRUE(AppendMessage(message, &framed));
  const double per_pose = static_cast<double>(framed.size()) / 4;
  RecordProperty("bytes_per_pose_sample", std::to_string(per_pose));
  RecordProperty("stroke_frame_bytes", std::to_string(framed.size()));
  std::printf("4-pose stroke: %zu bytes framed, %.2f bytes per pose sample\n", framed.size(),
              per_pose);
  // 44 bytes: one naive message per pose sample (the figure the issue names).
  EXPECT_LT(per_pose, 44);
}

}  // namespace
}  // namespace sculpt::codec
