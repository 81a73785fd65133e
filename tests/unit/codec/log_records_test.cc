/// @brief Unit tests for the edit log's records and skin files: every kind round-trips, the bytes
/// are the ones the server wrote before the records had domain types (built here with the
/// protobuf messages exactly as it built them), and damaged bytes are refused by name.
#include "sculpt/codec/log_records.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <variant>
#include <vector>

#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

template <typename Record>
Record DecodeAs(const std::string& bytes, uint64_t seq = 1) {
  auto d = DecodeLogRecord(seq, bytes);
  EXPECT_TRUE(d.ok()) << d.status();
  if (!d.ok()) return Record{};
  EXPECT_TRUE(std::holds_alternative<Record>(*d)) << "variant index " << d->index();
  if (!std::holds_alternative<Record>(*d)) return Record{};
  return std::get<Record>(*d);
}

std::string Tagged(char tag, const google::protobuf::MessageLite& m) {
  return std::string(1, tag) + m.SerializeAsString();
}

void ExpectSameEdit(const levelset::EditRequest& a, const levelset::EditRequest& b) {
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.tool.kind, b.tool.kind);
  EXPECT_EQ(a.tool.center, b.tool.center);
  EXPECT_EQ(a.tool.end, b.tool.end);
  EXPECT_EQ(a.tool.size, b.tool.size);
  EXPECT_EQ(a.speed, b.speed);
  EXPECT_EQ(a.dt, b.dt);
  EXPECT_EQ(a.amount, b.amount);
}

StrokePoseRecord Pose() {
  StrokePoseRecord p;
  p.global_seq = 41;
  p.client_id = 3;
  p.client_seq = 9;
  p.object = "clay";
  p.pose_index = 1;
  p.pose_count = 2;
  p.commit_ms = 1700000000123;
  p.edit.kind = levelset::EditKind::kAdd;
  p.edit.tool = levelset::ToolShape::Capsule({1.1, 2.2, 3.3}, {1.6, 2.2, 3.3}, 0.7);
  p.edit.speed = 12.5;
  p.edit.dt = 1.0 / 120;
  p.edit.amount = 0.3;
  return p;
}

Paint APaint() {
  Paint p;
  p.client_seq = 5;
  p.object = "clay";
  p.tool = levelset::ToolKind::kEllipsoid;
  p.tool_size = {1.5, 2, 2.5};
  p.position = {0.25, -1, 3};
  p.material = 2;
  p.weight = 0.75;
  return p;
}

SweepRecord ARevolution() {
  SweepRecord s;
  s.global_seq = 12;
  s.client_id = 4;
  s.client_seq = 6;
  s.object = "vase";
  s.request.mode = levelset::SweepRequest::Mode::kRevolve;
  s.request.add = false;
  s.request.depth = 0;
  s.request.plane = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}};
  s.request.outline = {{0, 0}, {1, 0}, {1, 1}, {0.5, 1.5}};
  s.request.axis_point = {0.25, 0};
  s.request.axis_dir = {std::cos(0.3), std::sin(0.3)};
  return s;
}

ModelEdit AModelEdit() {
  ModelEdit m;
  m.client_seq = 8;
  m.object = "part";
  m.intent.corner = 17;
  m.intent.offset = {1, 0, -1};
  m.intent.displacement = {0.125, -0.5, 2};
  m.intent.cell = 3;
  return m;
}

BallEdit ABallEdit() {
  BallEdit b;
  b.client_seq = 10;
  b.skin = "outline";
  b.op = BallOp::kAdd;
  b.index = 2;
  b.x = 1.5;
  b.y = -2;
  b.r = 3;
  b.theta = 0.25;
  return b;
}

class LogRecordsTest : public ::testing::Test {};

// --- Round trips -----------------------------------------------------------------------------

TEST_F(LogRecordsTest, StrokePoseRoundTripsAsLogged) {
  const StrokePoseRecord p = Pose();
  const auto back = DecodeAs<StrokePoseRecord>(EncodeLogRecord(p));
  EXPECT_EQ(back.global_seq, 41u);
  EXPECT_EQ(back.client_id, 3u);
  EXPECT_EQ(back.client_seq, 9u);
  EXPECT_EQ(back.object, "clay");
  EXPECT_EQ(back.pose_index, 1u);
  EXPECT_EQ(back.pose_count, 2u);
  EXPECT_EQ(back.commit_ms, 1700000000123u);
  EXPECT_TRUE(back.completes());
  // The numbers come back rounded to float: what AsLogged gives the live server.
  ExpectSameEdit(back.edit, AsLogged(p.edit));
  EXPECT_EQ(back.edit.tool.center.x, static_cast<float>(1.1));
  EXPECT_EQ(back.edit.dt, static_cast<float>(1.0 / 120));
}

TEST_F(LogRecordsTest, FirstPoseOfTwoDoesNotComplete) {
  StrokePoseRecord p = Pose();
  p.pose_index = 0;
  EXPECT_FALSE(DecodeAs<StrokePoseRecord>(EncodeLogRecord(p)).completes());
  p.pose_count = 0;  // older logs: a pose stands alone
  EXPECT_TRUE(DecodeAs<StrokePoseRecord>(EncodeLogRecord(p)).completes());
}

TEST_F(LogRecordsTest, PaintRoundTripsAsLogged) {
  PaintRecord r;
  r.global_seq = 7;
  r.client_id = 2;
  r.paint = APaint();
  const auto back = DecodeAs<PaintRecord>(EncodeLogRecord(r));
  EXPECT_EQ(back.global_seq, 7u);
  EXPECT_EQ(back.client_id, 2u);
  const Paint want = AsLogged(r.paint);
  EXPECT_EQ(back.paint.client_seq, 5u);
  EXPECT_EQ(back.paint.object, "clay");
  EXPECT_EQ(back.paint.tool, levelset::ToolKind::kEllipsoid);
  EXPECT_EQ(back.paint.tool_size, want.tool_size);
  EXPECT_EQ(back.paint.position, want.position);
  EXPECT_EQ(back.paint.material, 2u);
  EXPECT_EQ(back.paint.weight, 0.75);
  EXPECT_TRUE(back.paint.fractions.empty());
}

TEST_F(LogRecordsTest, SweepRoundTripsExactly) {
  const SweepRecord s = ARevolution();
  const auto back = DecodeAs<SweepRecord>(EncodeLogRecord(s));
  ASSERT_TRUE(back.request_status.ok()) << back.request_status;
  EXPECT_EQ(back.global_seq, 12u);
  EXPECT_EQ(back.client_id, 4u);
  EXPECT_EQ(back.client_seq, 6u);
  EXPECT_EQ(back.object, "vase");
  EXPECT_EQ(back.request.mode, levelset::SweepRequest::Mode::kRevolve);
  EXPECT_FALSE(back.request.add);
  EXPECT_EQ(back.request.depth, 0);
  EXPECT_EQ(back.request.plane.origin, s.request.plane.origin);
  EXPECT_EQ(back.request.plane.u, s.request.plane.u);
  EXPECT_EQ(back.request.plane.v, s.request.plane.v);
  ASSERT_EQ(back.request.outline.size(), 4u);
  EXPECT_EQ(back.request.outline[3].x, 0.5);
  EXPECT_EQ(back.request.outline[3].y, 1.5);
  EXPECT_EQ(back.request.axis_point.x, 0.25);
  EXPECT_EQ(back.request.axis_dir.x, std::cos(0.3));
  EXPECT_EQ(back.request.axis_dir.y, std::sin(0.3));
}

TEST_F(LogRecordsTest, ExtrusionLogsNoAxis) {
  SweepRecord s = ARevolution();
  s.request.mode = levelset::SweepRequest::Mode::kExtrude;
  s.request.add = true;
  s.request.depth = 2.5;
  const std::string bytes = EncodeLogRecord(s);
  v1::SkinSweepRecord r;
  ASSERT_TRUE(r.ParseFromString(bytes.substr(1)));
  EXPECT_EQ(r.axis_size(), 0);
  const auto back = DecodeAs<SweepRecord>(bytes);
  EXPECT_EQ(back.request.mode, levelset::SweepRequest::Mode::kExtrude);
  EXPECT_TRUE(back.request.add);
  EXPECT_EQ(back.request.depth, 2.5);
  const levelset::SweepRequest defaults;
  EXPECT_EQ(back.request.axis_dir.x, defaults.axis_dir.x);
}

TEST_F(LogRecordsTest, ModelIntentRoundTrips) {
  ModelRecord m;
  m.global_seq = 30;
  m.client_id = 6;
  m.edit = AModelEdit();
  m.edit.intent.set_flags = hetero::CornerFlags{true, false};
  m.model_version = 4;
  const auto back = DecodeAs<ModelRecord>(EncodeLogRecord(m));
  EXPECT_EQ(back.global_seq, 30u);
  EXPECT_EQ(back.client_id, 6u);
  EXPECT_EQ(back.model_version, 4u);
  EXPECT_EQ(back.edit.client_seq, 8u);
  EXPECT_EQ(back.edit.object, "part");
  EXPECT_EQ(back.edit.intent.corner, 17u);
  EXPECT_EQ(back.edit.intent.offset, (std::array<int, 3>{1, 0, -1}));
  EXPECT_EQ(back.edit.intent.displacement, m.edit.intent.displacement);
  EXPECT_EQ(back.edit.intent.cell, 3);
  ASSERT_TRUE(back.edit.intent.set_flags.has_value());
  EXPECT_TRUE(back.edit.intent.set_flags->geometry_c1);
  EXPECT_FALSE(back.edit.intent.set_flags->material_c1);
}

TEST_F(LogRecordsTest, BallEditRoundTrips) {
  BallEditRecord b;
  b.global_seq = 50;
  b.client_id = 1;
  b.edit = ABallEdit();
  b.skin_version = 11;
  const auto back = DecodeAs<BallEditRecord>(EncodeLogRecord(b));
  ASSERT_TRUE(back.edit_status.ok()) << back.edit_status;
  EXPECT_EQ(back.global_seq, 50u);
  EXPECT_EQ(back.client_id, 1u);
  EXPECT_EQ(back.skin_version, 11u);
  EXPECT_EQ(back.edit.client_seq, 10u);
  EXPECT_EQ(back.edit.skin, "outline");
  EXPECT_EQ(back.edit.op, BallOp::kAdd);
  EXPECT_EQ(back.edit.index, 2u);
  EXPECT_EQ(back.edit.x, 1.5);
  EXPECT_EQ(back.edit.y, -2);
  EXPECT_EQ(back.edit.r, 3);
  EXPECT_EQ(back.edit.theta, 0.25);
}

TEST_F(LogRecordsTest, UndoRoundTrips) {
  UndoRecord u{7, 3, 2, "clay", true, "3"};
  const auto back = DecodeAs<UndoRecord>(EncodeLogRecord(u));
  EXPECT_EQ(back.global_seq, 7u);
  EXPECT_EQ(back.client_id, 3u);
  EXPECT_EQ(back.client_seq, 2u);
  EXPECT_EQ(back.object, "clay");
  EXPECT_TRUE(back.redo);
  EXPECT_EQ(back.author, "3");
}

// The undo's choice (which history, which edit) is logged so that recovery takes back the same
// edit; records without it read as the object's stroke history (book 0).
TEST_F(LogRecordsTest, UndoTargetRoundTripsAndOlderRecordsReadAsBookZero) {
  UndoRecord u{9, 3, 4, "profile", false, "3"};
  u.target_book = 2;
  u.target_seq = 6;
  const auto back = DecodeAs<UndoRecord>(EncodeLogRecord(u));
  EXPECT_EQ(back.target_book, 2u);
  EXPECT_EQ(back.target_seq, 6u);
  EXPECT_EQ(back.object, "profile");
  const auto old = DecodeAs<UndoRecord>(EncodeLogRecord(UndoRecord{7, 3, 2, "clay", true, "3"}));
  EXPECT_EQ(old.target_book, 0u);
  EXPECT_EQ(old.target_seq, 0u);
}

TEST_F(LogRecordsTest, SavedSkinRoundTrips) {
  SavedSkin s;
  s.seq = 900;
  s.version = 12;
  s.balls = {{0, 0, 1, 0}, {2.5, -1, 0.5, 0.125}};
  s.last_edit_seq = {{1, 4}, {2, 9}};
  s.last_sweep_seq = {{3, 1}};
  auto back = DecodeSavedSkin(EncodeSavedSkin(s));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->seq, 900u);
  EXPECT_EQ(back->version, 12u);
  ASSERT_EQ(back->balls.size(), 2u);
  EXPECT_EQ(back->balls[1].x, 2.5);
  EXPECT_EQ(back->balls[1].y, -1);
  EXPECT_EQ(back->balls[1].r, 0.5);
  EXPECT_EQ(back->balls[1].theta, 0.125);
  EXPECT_EQ(back->last_edit_seq, s.last_edit_seq);
  EXPECT_EQ(back->last_sweep_seq, s.last_sweep_seq);
}

// --- The bytes the server wrote before (built as its scene code built them) -------------------

TEST_F(LogRecordsTest, StrokePoseBytesAreTheEditRecordsTheServerWrote) {
  const StrokePoseRecord p = Pose();
  v1::EditRecord r = RecordFromEdit(p.edit);
  r.set_client_id(3);
  r.set_client_seq(9);
  r.set_pose_index(1);
  r.set_object("clay");
  r.set_global_seq(41);
  r.set_pose_count(2);
  r.set_commit_ms(1700000000123);
  EXPECT_EQ(EncodeLogRecord(p), r.SerializeAsString());
  EXPECT_EQ(EncodeLogRecord(p)[0], '\x08') << "a pose never starts with a LogTag";
}

TEST_F(LogRecordsTest, PaintBytesAreTheServersTagThenPaintRecord) {
  PaintRecord p{7, 2, APaint()};
  v1::PaintRecord r;
  r.set_global_seq(7);
  r.set_client_id(2);
  *r.mutable_edit() = EncodePaintEdit(APaint());
  EXPECT_EQ(EncodeLogRecord(p), Tagged('\x01', r));
}

TEST_F(LogRecordsTest, SweepBytesAreTheServersTagThenSkinSweepRecord) {
  const SweepRecord s = ARevolution();
  v1::SkinSweepRecord r;
  r.set_client_id(4);
  r.set_client_seq(6);
  r.set_object("vase");
  r.set_mode(v1::SKIN_SWEEP_MODE_REVOLVE);
  r.set_kind(v1::EDIT_KIND_SUBTRACT);
  r.set_depth(0);
  for (double v : {0, 0, 1, 1, 0, 0, 0, 1, 0}) r.add_plane(v);
  for (double v : {0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.5, 1.5}) r.add_outline(v);
  for (double v : {0.25, 0.0, std::cos(0.3), std::sin(0.3)}) r.add_axis(v);
  r.set_global_seq(12);
  EXPECT_EQ(EncodeLogRecord(s), Tagged('\x00', r));
}

TEST_F(LogRecordsTest, ModelBytesAreTheServersTagThenModelRecord) {
  ModelRecord m{30, 6, AModelEdit(), 4};
  v1::ModelRecord r;
  r.set_global_seq(30);
  r.set_client_id(6);
  *r.mutable_intent() = EncodeModelIntent(AModelEdit());
  r.set_model_version(4);
  EXPECT_EQ(EncodeLogRecord(m), Tagged('\x02', r));
}

TEST_F(LogRecordsTest, BallEditBytesAreTheServersTagThenSkinEditRecord) {
  BallEditRecord b;
  b.global_seq = 50;
  b.client_id = 1;
  b.edit = ABallEdit();
  b.skin_version = 11;
  v1::SkinEditRecord r;
  r.set_global_seq(50);
  r.set_client_id(1);
  *r.mutable_edit() = EncodeSkinBallEdit(ABallEdit());
  r.set_skin_version(11);
  EXPECT_EQ(EncodeLogRecord(b), Tagged('\x03', r));
}

TEST_F(LogRecordsTest, UndoBytesAreTheGoldenOnes) {
  // 0x04, then UndoRecord{global_seq 7, client_id 3, request{client_seq 2, "clay", redo}, "3"}.
  const std::string golden(
      "\x04\x08\x07\x10\x03\x1a\x0a\x08\x02\x12\x04"
      "clay\x18\x01\x22\x01"
      "3",
      20);
  EXPECT_EQ(EncodeLogRecord(UndoRecord{7, 3, 2, "clay", true, "3"}), golden);
}

TEST_F(LogRecordsTest, SavedSkinBytesAreTheServersSavedSkin) {
  SavedSkin s;
  s.seq = 900;
  s.version = 12;
  s.balls = {{0, 0, 1, 0}, {2.5, -1, 0.5, 0.125}};
  v1::SavedSkin saved;
  saved.set_seq(900);
  saved.set_version(12);
  for (const SkinBall& o : s.balls) {
    v1::SkinBall* b = saved.add_balls();
    b->set_x(o.x);
    b->set_y(o.y);
    b->set_r(o.r);
    b->set_theta(o.theta);
  }
  EXPECT_EQ(EncodeSavedSkin(s), saved.SerializeAsString());
}

// --- Ownership epochs (cluster mode) ----------------------------------------------------------

// Every kind's encoded bytes, as the commit pipeline builds them before it appends the user and
// the epoch.
std::vector<std::string> EveryKind() {
  PaintRecord paint;
  paint.global_seq = 2;
  paint.client_id = 3;
  paint.paint = APaint();
  ModelRecord model;
  model.global_seq = 4;
  model.client_id = 3;
  model.edit = AModelEdit();
  model.model_version = 6;
  BallEditRecord ball;
  ball.global_seq = 5;
  ball.client_id = 3;
  ball.edit = ABallEdit();
  ball.skin_version = 2;
  return {EncodeLogRecord(Pose()),      EncodeLogRecord(paint),
          EncodeLogRecord(ARevolution()), EncodeLogRecord(model),
          EncodeLogRecord(ball),        EncodeLogRecord(UndoRecord{7, 3, 2, "clay", true, "3"})};
}

TEST_F(LogRecordsTest, EveryKindCarriesTheEpochAppendedAfterTheUser) {
  const std::vector<std::string> kinds = EveryKind();
  ASSERT_EQ(kinds.size(), std::variant_size_v<EditLogRecord>) << "a kind is missing here";
  for (size_t i = 0; i < kinds.size(); ++i) {
    std::string bytes = kinds[i];
    AppendRecordUser(&bytes, "ada");
    AppendRecordEpoch(&bytes, 9);
    auto d = DecodeLogRecord(50 + i, bytes);
    ASSERT_TRUE(d.ok()) << "kind " << i << ": " << d.status();
    EXPECT_EQ(d->index(), i) << "appending the epoch changed the kind";
    EXPECT_EQ(RecordEpoch(*d), 9u) << "kind " << i;
    EXPECT_EQ(std::visit([](const auto& r) { return r.user; }, *d), "ada") << "kind " << i;
    // The rest of the record is what it was without the epoch.
    auto plain = DecodeLogRecord(50 + i, kinds[i]);
    ASSERT_TRUE(plain.ok()) << plain.status();
    EXPECT_EQ(RecordEpoch(*plain), 0u) << "kind " << i;
    EXPECT_EQ(std::visit([](const auto& r) { return r.global_seq; }, *d),
              std::visit([](const auto& r) { return r.global_seq; }, *plain));
    // A large epoch (a varint of ten bytes) reads back too.
    std::string big = kinds[i];
    AppendRecordEpoch(&big, UINT64_MAX);
    auto b = DecodeLogRecord(1, big);
    ASSERT_TRUE(b.ok()) << b.status();
    EXPECT_EQ(RecordEpoch(*b), UINT64_MAX) << "kind " << i;
  }
}

TEST_F(LogRecordsTest, EpochZeroLeavesEveryKindsBytesAsTheyWere) {
  for (const std::string& bytes : EveryKind()) {
    std::string with = bytes;
    AppendRecordEpoch(&with, 0);
    EXPECT_EQ(with, bytes) << "a single process must write the bytes it always wrote";
  }
}

TEST_F(LogRecordsTest, TaggedEpochIsFieldSixteenOfTheKindsOwnMessage) {
  // Other readers of the log (tools, older code) parse the message after the tag: the epoch is
  // that message's own field, not bytes it does not know.
  BallEditRecord ball;
  ball.edit = ABallEdit();
  std::string bytes = EncodeLogRecord(ball);
  AppendRecordEpoch(&bytes, 4);
  v1::SkinEditRecord r;
  ASSERT_TRUE(r.ParseFromString(bytes.substr(1)));
  EXPECT_EQ(r.epoch(), 4u);
  v1::UndoRecord u;
  std::string undo = EncodeLogRecord(UndoRecord{7, 3, 2, "clay", true, "3"});
  AppendRecordEpoch(&undo, 5);
  ASSERT_TRUE(u.ParseFromString(undo.substr(1)));
  EXPECT_EQ(u.epoch(), 5u);
}

// --- Damaged bytes ----------------------------------------------------------------------------

TEST_F(LogRecordsTest, RejectsTaggedRecordThatDoesNotParse) {
  const char* kinds[] = {"a sweep", "a paint", "a model intent", "a ball edit", "an undo"};
  for (char tag = 0; tag <= 4; ++tag) {
    const std::string garbage = std::string(1, tag) + "\xff\xff\xff";
    auto d = DecodeLogRecord(42, garbage);
    ASSERT_FALSE(d.ok()) << "tag " << int(tag);
    EXPECT_EQ(d.status().code(), Status::Code::kDataLoss);
    EXPECT_NE(d.status().message().find("42"), std::string::npos) << d.status();
    EXPECT_NE(d.status().message().find(kinds[static_cast<int>(tag)]), std::string::npos)
        << d.status();
  }
}

TEST_F(LogRecordsTest, RejectsTruncatedStrokePose) {
  const std::string bytes = EncodeLogRecord(Pose());
  auto d = DecodeLogRecord(77, bytes.substr(0, bytes.size() - 3));
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(d.status().message().find("77"), std::string::npos) << d.status();
}

TEST_F(LogRecordsTest, RejectsTruncatedBallEdit) {
  BallEditRecord b;
  b.edit = ABallEdit();
  const std::string bytes = EncodeLogRecord(b);
  auto d = DecodeLogRecord(5, bytes.substr(0, bytes.size() - 4));
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), Status::Code::kDataLoss);
}

TEST_F(LogRecordsTest, RejectsSweepWithoutNinePlaneValues) {
  v1::SkinSweepRecord r;
  r.set_object("vase");
  for (int i = 0; i < 8; ++i) r.add_plane(0);
  const auto back = DecodeAs<SweepRecord>(Tagged('\x00', r));
  EXPECT_EQ(back.request_status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(back.request_status.message().find("SkinSweepRecord.plane.size=8"), std::string::npos)
      << back.request_status;
  EXPECT_EQ(back.object, "vase") << "routing still knows the object";
}

TEST_F(LogRecordsTest, RejectsSweepWithOddOutline) {
  SweepRecord s = ARevolution();
  v1::SkinSweepRecord r;
  ASSERT_TRUE(r.ParseFromString(EncodeLogRecord(s).substr(1)));
  r.add_outline(1);
  const auto back = DecodeAs<SweepRecord>(Tagged('\x00', r));
  EXPECT_EQ(back.request_status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(back.request_status.message().find("SkinSweepRecord.outline.size=9"), std::string::npos)
      << back.request_status;
}

TEST_F(LogRecordsTest, RejectsRevolutionWithoutAxis) {
  SweepRecord s = ARevolution();
  v1::SkinSweepRecord r;
  ASSERT_TRUE(r.ParseFromString(EncodeLogRecord(s).substr(1)));
  r.clear_axis();
  const auto back = DecodeAs<SweepRecord>(Tagged('\x00', r));
  EXPECT_EQ(back.request_status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(back.request_status.message().find("SkinSweepRecord.axis.size=0"), std::string::npos)
      << back.request_status;
}

TEST_F(LogRecordsTest, RejectsBallEditWithUnknownOpButKeepsSkinAndSequence) {
  v1::SkinEditRecord r;
  r.set_client_id(1);
  *r.mutable_edit() = EncodeSkinBallEdit(ABallEdit());
  r.mutable_edit()->set_op(static_cast<v1::SkinBallOp>(9));
  const auto back = DecodeAs<BallEditRecord>(Tagged('\x03', r));
  EXPECT_EQ(back.edit_status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(back.edit_status.message().find("SkinBallEdit.op"), std::string::npos)
      << back.edit_status;
  EXPECT_EQ(back.edit.skin, "outline");
  EXPECT_EQ(back.edit.client_seq, 10u);
}

TEST_F(LogRecordsTest, RejectsDamagedSavedSkin) {
  SavedSkin s;
  s.balls = {{0, 0, 1, 0}};
  const std::string bytes = EncodeSavedSkin(s);
  auto d = DecodeSavedSkin(bytes.substr(0, bytes.size() - 2));
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), Status::Code::kDataLoss);
}

}  // namespace
}  // namespace sculpt::codec
