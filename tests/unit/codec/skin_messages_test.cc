/// @brief Unit tests for decoding the skin messages: each refusal names field, value and range.
#include "sculpt/codec/skin_messages.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "unit/codec/field_violation.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

using testing::IsViolation;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
const std::string kLongName(65, 'a');

v1::SkinBallEdit Ball(v1::SkinBallOp op) {
  v1::SkinBallEdit e;
  e.set_client_seq(9);
  e.set_skin("outline");
  e.set_op(op);
  e.set_index(2);
  e.mutable_ball()->set_x(1.5);
  e.mutable_ball()->set_y(-2);
  e.mutable_ball()->set_r(3);
  e.mutable_ball()->set_theta(0.25);
  return e;
}

class DecodeSkinBallEditTest : public ::testing::Test {};

TEST_F(DecodeSkinBallEditTest, AcceptsAddWithEveryBallField) {
  auto e = DecodeSkinBallEdit(Ball(v1::SKIN_BALL_OP_ADD));
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->client_seq, 9u);
  EXPECT_EQ(e->skin, "outline");
  EXPECT_EQ(e->op, BallOp::kAdd);
  EXPECT_EQ(e->index, 2u);
  EXPECT_EQ(e->x, 1.5);
  EXPECT_EQ(e->y, -2);
  EXPECT_EQ(e->r, 3);
  EXPECT_EQ(e->theta, 0.25);
}

TEST_F(DecodeSkinBallEditTest, MoveCarriesNoUncheckedTheta) {
  v1::SkinBallEdit m = Ball(v1::SKIN_BALL_OP_MOVE);
  m.mutable_ball()->set_theta(kNan);  // unused by a move: not checked, not passed on
  auto e = DecodeSkinBallEdit(m);
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->theta, 0);
  EXPECT_EQ(e->r, 3);
}

TEST_F(DecodeSkinBallEditTest, OrientAndRemoveCarryOnlyWhatTheyUse) {
  v1::SkinBallEdit o = Ball(v1::SKIN_BALL_OP_ORIENT);
  o.mutable_ball()->set_r(-5);  // unused by an orient
  auto e = DecodeSkinBallEdit(o);
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->r, 0);
  EXPECT_EQ(e->theta, 0.25);
  v1::SkinBallEdit r = Ball(v1::SKIN_BALL_OP_REMOVE);
  r.mutable_ball()->set_x(kNan);
  auto d = DecodeSkinBallEdit(r);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->op, BallOp::kRemove);
  EXPECT_EQ(d->x, 0);
}

TEST_F(DecodeSkinBallEditTest, EncodeDecodesBackToTheSameEdit) {
  auto e = DecodeSkinBallEdit(Ball(v1::SKIN_BALL_OP_ADD));
  ASSERT_TRUE(e.ok());
  auto back = DecodeSkinBallEdit(EncodeSkinBallEdit(*e));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->client_seq, e->client_seq);
  EXPECT_EQ(back->skin, e->skin);
  EXPECT_EQ(back->op, e->op);
  EXPECT_EQ(back->index, e->index);
  EXPECT_EQ(back->x, e->x);
  EXPECT_EQ(back->y, e->y);
  EXPECT_EQ(back->r, e->r);
  EXPECT_EQ(back->theta, e->theta);
}

TEST_F(DecodeSkinBallEditTest, RejectsSkinEmpty) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_ADD);
  e.set_skin("");
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.skin", "",
                          "names of 1..64 bytes"));
}

TEST_F(DecodeSkinBallEditTest, RejectsSkinTooLong) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_ADD);
  e.set_skin(kLongName);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.skin", kLongName,
                          "names of 1..64 bytes"));
}

TEST_F(DecodeSkinBallEditTest, RejectsOpUnspecified) {
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(Ball(v1::SKIN_BALL_OP_UNSPECIFIED)).status(),
                          "SkinBallEdit.op", "0",
                          "{1 (ADD), 2 (MOVE), 3 (REMOVE), 4 (ORIENT)}"));
}

TEST_F(DecodeSkinBallEditTest, RejectsOpUnknown) {
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(Ball(static_cast<v1::SkinBallOp>(77))).status(),
                          "SkinBallEdit.op", "77",
                          "{1 (ADD), 2 (MOVE), 3 (REMOVE), 4 (ORIENT)}"));
}

TEST_F(DecodeSkinBallEditTest, RejectsIndexAtMaxBalls) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_REMOVE);
  e.set_index(kMaxSkinBalls);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.index", "4096",
                          "[0, 4095]"));
}

TEST_F(DecodeSkinBallEditTest, RejectsBallXOutsideCoordinates) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_MOVE);
  e.mutable_ball()->set_x(2e6);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.ball.x", "2e+06",
                          "[-1e+06, 1e+06]"));
}

TEST_F(DecodeSkinBallEditTest, RejectsBallXNan) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_ADD);
  e.mutable_ball()->set_x(kNan);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.ball.x", "nan",
                          "finite numbers"));
}

TEST_F(DecodeSkinBallEditTest, RejectsBallYOutsideCoordinates) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_ADD);
  e.mutable_ball()->set_y(-3e6);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.ball.y", "-3e+06",
                          "[-1e+06, 1e+06]"));
}

TEST_F(DecodeSkinBallEditTest, RejectsBallRBelowMinimum) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_MOVE);
  e.mutable_ball()->set_r(0);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.ball.r", "0",
                          "[0.001, 1e+06]"));
}

TEST_F(DecodeSkinBallEditTest, RejectsBallThetaOutside) {
  v1::SkinBallEdit e = Ball(v1::SKIN_BALL_OP_ORIENT);
  e.mutable_ball()->set_theta(65);
  EXPECT_TRUE(IsViolation(DecodeSkinBallEdit(e).status(), "SkinBallEdit.ball.theta", "65",
                          "[-64, 64]"));
}

v1::SkinSweep Sweep(v1::SkinSweepMode mode) {
  v1::SkinSweep s;
  s.set_client_seq(4);
  s.set_skin("outline");
  s.set_object("clay");
  s.set_mode(mode);
  s.set_kind(v1::EDIT_KIND_SUBTRACT);
  s.set_depth(2.5);
  s.set_axis_x(1);
  s.set_axis_y(-1);
  s.set_axis_angle(0.5);
  return s;
}

class DecodeSkinSweepTest : public ::testing::Test {};

TEST_F(DecodeSkinSweepTest, AcceptsExtrusionWithoutAxis) {
  auto s = DecodeSkinSweep(Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->client_seq, 4u);
  EXPECT_EQ(s->skin, "outline");
  EXPECT_EQ(s->object, "clay");
  EXPECT_EQ(s->mode, levelset::SweepRequest::Mode::kExtrude);
  EXPECT_FALSE(s->add);
  EXPECT_EQ(s->depth, 2.5);
  EXPECT_EQ(s->axis_x, 0);
  EXPECT_EQ(s->axis_angle, 0);
}

TEST_F(DecodeSkinSweepTest, AcceptsRevolutionWithoutDepth) {
  v1::SkinSweep w = Sweep(v1::SKIN_SWEEP_MODE_REVOLVE);
  w.set_depth(kNan);  // unused by a revolution
  w.set_kind(v1::EDIT_KIND_ADD);
  auto s = DecodeSkinSweep(w);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->mode, levelset::SweepRequest::Mode::kRevolve);
  EXPECT_TRUE(s->add);
  EXPECT_EQ(s->depth, 0);
  EXPECT_EQ(s->axis_x, 1);
  EXPECT_EQ(s->axis_y, -1);
  EXPECT_EQ(s->axis_angle, 0.5);
}

TEST_F(DecodeSkinSweepTest, RejectsSkinEmpty) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_skin("");
  EXPECT_TRUE(
      IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.skin", "", "names of 1..64 bytes"));
}

TEST_F(DecodeSkinSweepTest, RejectsObjectTooLong) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_object(kLongName);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.object", kLongName,
                          "names of 1..64 bytes"));
}

TEST_F(DecodeSkinSweepTest, RejectsModeUnspecified) {
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(Sweep(v1::SKIN_SWEEP_MODE_UNSPECIFIED)).status(),
                          "SkinSweep.mode", "0", "{1 (EXTRUDE), 2 (REVOLVE)}"));
}

TEST_F(DecodeSkinSweepTest, RejectsKindPress) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_kind(v1::EDIT_KIND_PRESS);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.kind", "1",
                          "{2 (ADD), 3 (SUBTRACT)}"));
}

TEST_F(DecodeSkinSweepTest, RejectsDepthZero) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_depth(0);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.depth", "0", "(0, 1e+06]"));
}

TEST_F(DecodeSkinSweepTest, RejectsDepthNegative) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_depth(-1);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.depth", "-1", "[0, 1e+06]"));
}

TEST_F(DecodeSkinSweepTest, RejectsDepthNan) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_EXTRUDE);
  s.set_depth(kNan);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.depth", "nan",
                          "finite numbers"));
}

TEST_F(DecodeSkinSweepTest, RejectsAxisXOutsideCoordinates) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_REVOLVE);
  s.set_axis_x(1e7);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.axis_x", "1e+07",
                          "[-1e+06, 1e+06]"));
}

TEST_F(DecodeSkinSweepTest, RejectsAxisYNan) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_REVOLVE);
  s.set_axis_y(kNan);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.axis_y", "nan",
                          "finite numbers"));
}

TEST_F(DecodeSkinSweepTest, RejectsAxisAngleOutside) {
  v1::SkinSweep s = Sweep(v1::SKIN_SWEEP_MODE_REVOLVE);
  s.set_axis_angle(-100);
  EXPECT_TRUE(IsViolation(DecodeSkinSweep(s).status(), "SkinSweep.axis_angle", "-100",
                          "[-64, 64]"));
}

v1::ContourSubscribe Slice() {
  v1::ContourSubscribe c;
  v1::ContourSlice* s = c.mutable_slice();
  s->set_object("clay");
  s->mutable_origin()->set_z(1);
  s->mutable_u()->set_x(1);
  s->mutable_v()->set_y(1);
  s->set_step(0.5);
  s->set_half_extent(16);
  return c;
}

class DecodeContourSubscribeTest : public ::testing::Test {};

TEST_F(DecodeContourSubscribeTest, AcceptsSkin) {
  v1::ContourSubscribe c;
  c.set_skin("outline");
  auto r = DecodeContourSubscribe(c);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->skin, "outline");
  EXPECT_TRUE(r->object.empty());
  EXPECT_FALSE(r->unsubscribe);
}

TEST_F(DecodeContourSubscribeTest, AcceptsSlice) {
  auto r = DecodeContourSubscribe(Slice());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->skin.empty());
  EXPECT_EQ(r->object, "clay");
  EXPECT_EQ(r->plane.origin.z, 1);
  EXPECT_EQ(r->plane.u.x, 1);
  EXPECT_EQ(r->plane.v.y, 1);
  EXPECT_EQ(r->step, 0.5);
  EXPECT_EQ(r->half_extent, 16);
}

TEST_F(DecodeContourSubscribeTest, AcceptsSliceUnsubscribeWithoutPlane) {
  v1::ContourSubscribe c;
  c.mutable_slice()->set_object("clay");
  c.set_unsubscribe(true);
  auto r = DecodeContourSubscribe(c);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->unsubscribe);
  EXPECT_EQ(r->object, "clay");
}

TEST_F(DecodeContourSubscribeTest, RejectsSkinTooLong) {
  v1::ContourSubscribe c;
  c.set_skin(kLongName);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.skin", kLongName,
                          "names of 1..64 bytes"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSkinMissingWithoutSlice) {
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(v1::ContourSubscribe()).status(),
                          "ContourSubscribe.skin", "", "names of 1..64 bytes (or set slice)"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceObjectEmpty) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->set_object("");
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.slice.object", "",
                          "names of 1..64 bytes"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceUNotUnit) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->mutable_u()->set_x(2);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.slice.u",
                          "(2, 0, 0)", "unit vectors (length 2, within 1e-6 of 1)"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceVNotOrthogonal) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->mutable_v()->set_x(1);
  c.mutable_slice()->mutable_v()->set_y(0);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.slice.v",
                          "(1, 0, 0)", "vectors orthogonal to u (u.v=1, |u.v| <= 1e-6)"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceOriginNan) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->mutable_origin()->set_x(std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.slice.origin",
                          "(nan, 0, 1)", "finite numbers"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceStepTooSmall) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->set_step(0);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(), "ContourSubscribe.slice.step", "0",
                          "[0.001, 1000]"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceHalfExtentBelowStep) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->set_half_extent(0.25);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(),
                          "ContourSubscribe.slice.half_extent", "0.25", "[0.5, 255.75]"));
}

TEST_F(DecodeContourSubscribeTest, RejectsSliceHalfExtentAboveSamples) {
  v1::ContourSubscribe c = Slice();
  c.mutable_slice()->set_half_extent(300);
  EXPECT_TRUE(IsViolation(DecodeContourSubscribe(c).status(),
                          "ContourSubscribe.slice.half_extent", "300", "[0.5, 255.75]"));
}

}  // namespace
}  // namespace sculpt::codec
