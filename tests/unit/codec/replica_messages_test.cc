/// @brief Unit tests for decoding Subscribe, SetInterest and ViewerSubscribe: each refusal names
/// field, value and range.
#include "sculpt/codec/replica_messages.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "unit/codec/field_violation.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

using testing::IsViolation;

constexpr float kNanF = std::numeric_limits<float>::quiet_NaN();
constexpr float kInfF = std::numeric_limits<float>::infinity();

void SetBox(v1::Box3* b, float lo, float hi) {
  for (v1::Vec3f* v : {b->mutable_min(), b->mutable_max()}) {
    const float c = v == b->mutable_min() ? lo : hi;
    v->set_x(c);
    v->set_y(c);
    v->set_z(c);
  }
}

v1::Subscribe MakeSubscribe() {
  v1::Subscribe s;
  s.set_object("clay");
  s.set_mode(v1::REPLICA_MODE_LEAF_DELTA);
  s.set_have_seq(12);
  SetBox(s.mutable_interest(), -4, 4);
  return s;
}

class DecodeSubscribeTest : public ::testing::Test {};

TEST_F(DecodeSubscribeTest, AcceptsABox) {
  auto r = DecodeSubscribe(MakeSubscribe());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->object, "clay");
  EXPECT_EQ(r->mode, ReplicaMode::kLeafDelta);
  EXPECT_EQ(r->have_seq, 12u);
  ASSERT_TRUE(r->interest.has_value());
  EXPECT_EQ(r->interest->min.y, -4);
  EXPECT_EQ(r->interest->max.z, 4);
}

TEST_F(DecodeSubscribeTest, AcceptsTheWholeObject) {
  v1::Subscribe s = MakeSubscribe();
  s.clear_interest();
  s.set_mode(v1::REPLICA_MODE_REPLAY);
  auto r = DecodeSubscribe(s);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->mode, ReplicaMode::kReplay);
  EXPECT_FALSE(r->interest.has_value());
}

TEST_F(DecodeSubscribeTest, RejectsModeUnspecified) {
  v1::Subscribe s = MakeSubscribe();
  s.set_mode(v1::REPLICA_MODE_UNSPECIFIED);
  EXPECT_TRUE(IsViolation(DecodeSubscribe(s).status(), "Subscribe.mode", "0",
                          "{1 (REPLAY), 2 (LEAF_DELTA)}"));
}

TEST_F(DecodeSubscribeTest, RejectsModeUnknown) {
  v1::Subscribe s = MakeSubscribe();
  s.set_mode(static_cast<v1::ReplicaMode>(9));
  EXPECT_TRUE(IsViolation(DecodeSubscribe(s).status(), "Subscribe.mode", "9",
                          "{1 (REPLAY), 2 (LEAF_DELTA)}"));
}

TEST_F(DecodeSubscribeTest, RejectsInterestMinNan) {
  v1::Subscribe s = MakeSubscribe();
  s.mutable_interest()->mutable_min()->set_y(kNanF);
  EXPECT_TRUE(IsViolation(DecodeSubscribe(s).status(), "Subscribe.interest.min", "(-4, nan, -4)",
                          "finite numbers"));
}

TEST_F(DecodeSubscribeTest, RejectsInterestMaxInfinite) {
  v1::Subscribe s = MakeSubscribe();
  s.mutable_interest()->mutable_max()->set_x(kInfF);
  EXPECT_TRUE(IsViolation(DecodeSubscribe(s).status(), "Subscribe.interest.max", "(inf, 4, 4)",
                          "finite numbers"));
}

class DecodeSetInterestTest : public ::testing::Test {};

TEST_F(DecodeSetInterestTest, AcceptsABoxAndTheWholeObject) {
  v1::SetInterest si;
  si.set_object("clay");
  auto whole = DecodeSetInterest(si);
  ASSERT_TRUE(whole.ok()) << whole.status();
  EXPECT_FALSE(whole->interest.has_value());
  SetBox(si.mutable_interest(), 1, 2);
  auto box = DecodeSetInterest(si);
  ASSERT_TRUE(box.ok()) << box.status();
  ASSERT_TRUE(box->interest.has_value());
  EXPECT_EQ(box->object, "clay");
  EXPECT_EQ(box->interest->min.x, 1);
  EXPECT_EQ(box->interest->max.x, 2);
}

TEST_F(DecodeSetInterestTest, RejectsInterestMaxNan) {
  v1::SetInterest si;
  si.set_object("clay");
  SetBox(si.mutable_interest(), 1, 2);
  si.mutable_interest()->mutable_max()->set_z(kNanF);
  EXPECT_TRUE(IsViolation(DecodeSetInterest(si).status(), "SetInterest.interest.max",
                          "(2, 2, nan)", "finite numbers"));
}

class DecodeViewerSubscribeTest : public ::testing::Test {};

TEST_F(DecodeViewerSubscribeTest, AcceptsARateAndTheDefault) {
  v1::ViewerSubscribe v;
  v.set_object("clay");
  auto d = DecodeViewerSubscribe(v);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->max_rate_hz, 0);
  v.set_max_rate_hz(30);
  auto r = DecodeViewerSubscribe(v);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->object, "clay");
  EXPECT_EQ(r->max_rate_hz, 30);
}

TEST_F(DecodeViewerSubscribeTest, RejectsMaxRateHzBelowMinimum) {
  v1::ViewerSubscribe v;
  v.set_object("clay");
  v.set_max_rate_hz(0.05f);
  EXPECT_TRUE(IsViolation(DecodeViewerSubscribe(v).status(), "ViewerSubscribe.max_rate_hz", "0.05",
                          "[0.1, 120] (0: the server's default)"));
}

TEST_F(DecodeViewerSubscribeTest, RejectsMaxRateHzAboveMaximum) {
  v1::ViewerSubscribe v;
  v.set_object("clay");
  v.set_max_rate_hz(500);
  EXPECT_TRUE(IsViolation(DecodeViewerSubscribe(v).status(), "ViewerSubscribe.max_rate_hz", "500",
                          "[0.1, 120] (0: the server's default)"));
}

TEST_F(DecodeViewerSubscribeTest, RejectsMaxRateHzNan) {
  v1::ViewerSubscribe v;
  v.set_object("clay");
  v.set_max_rate_hz(kNanF);
  EXPECT_TRUE(IsViolation(DecodeViewerSubscribe(v).status(), "ViewerSubscribe.max_rate_hz", "nan",
                          "[0.1, 120] (0: the server's default)"));
}

TEST(DecodeDivergenceReportTest, CarriesEveryField) {
  v1::DivergenceReport r;
  r.set_object("clay");
  r.set_global_seq(41);
  r.set_expected_hash(0x1234);
  r.set_actual_hash(0x5678);
  const Divergence d = DecodeDivergenceReport(r);
  EXPECT_EQ(d.object, "clay");
  EXPECT_EQ(d.global_seq, 41u);
  EXPECT_EQ(d.expected_hash, 0x1234u);
  EXPECT_EQ(d.actual_hash, 0x5678u);
}

}  // namespace
}  // namespace sculpt::codec
