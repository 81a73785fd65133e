// The wire acks of the scene's edit outcomes (net/wire_acks.h): accepted acks carry the outcome,
// refusals the Error ToWireError builds, and zero fields stay unsent.
#include "net/wire_acks.h"

#include <gtest/gtest.h>

#include "net/wire_error.h"

namespace sculpt::server {
namespace {

TEST(WireAcksTest, SkinAckOfAnAcceptedBallEdit) {
  SkinOutcome o;
  o.client_seq = 5;
  o.global_seq = 40;
  o.changed_sections = 2;
  o.balls = 6;
  const v1::SkinAck a = ToWireAck(o);
  EXPECT_TRUE(a.accepted());
  EXPECT_FALSE(a.has_error());
  EXPECT_EQ(a.client_seq(), 5u);
  EXPECT_EQ(a.global_seq(), 40u);
  EXPECT_EQ(a.changed_sections(), 2u);
  EXPECT_EQ(a.balls(), 6u);
  EXPECT_FALSE(a.duplicate());
}

TEST(WireAcksTest, SkinAckOfARefusalCarriesTheError) {
  SkinOutcome o{NotFound("SkinSweep.skin=nope outside the scene's skins"), 9};
  o.global_seq = 12;  // a sweep the kernel refused after it was logged
  const v1::SkinAck a = ToWireAck(o);
  EXPECT_FALSE(a.accepted());
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().code(), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(a.error().field(), "SkinSweep.skin");
  EXPECT_EQ(a.error().value(), "nope");
  EXPECT_EQ(a.error().allowed_range(), "the scene's skins");
  EXPECT_EQ(a.error().client_seq(), 9u);
  EXPECT_EQ(a.client_seq(), 9u);
  EXPECT_EQ(a.global_seq(), 12u);
}

TEST(WireAcksTest, SkinAckOfARefusalSendsNoAcceptedDetails) {
  SkinOutcome o{InvalidArgument("SkinBallEdit.index=9 outside [0, 4]"), 3};
  o.balls = 5;  // not reported for a refusal
  v1::SkinAck expected;
  expected.set_client_seq(3);
  *expected.mutable_error() = ToWireError(o.status, 3);
  EXPECT_EQ(ToWireAck(o).SerializeAsString(), expected.SerializeAsString());
}

TEST(WireAcksTest, PaintAckOfAnAcceptedPaint) {
  PaintOutcome o;
  o.client_seq = 2;
  o.global_seq = 77;
  o.changed_voxels = 300;
  o.dirty_leaves = 4;
  const v1::PaintAck a = ToWireAck(o);
  EXPECT_TRUE(a.accepted());
  EXPECT_FALSE(a.has_error());
  EXPECT_EQ(a.client_seq(), 2u);
  EXPECT_EQ(a.global_seq(), 77u);
  EXPECT_EQ(a.changed_voxels(), 300u);
  EXPECT_EQ(a.dirty_leaves(), 4u);
}

TEST(WireAcksTest, PaintAckOfARefusalCarriesTheError) {
  const v1::PaintAck a =
      ToWireAck(PaintOutcome{FailedPrecondition("PaintEdit.object=clay outside objects with "
                                                "materials"),
                             6});
  EXPECT_FALSE(a.accepted());
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(a.error().field(), "PaintEdit.object");
  EXPECT_EQ(a.error().value(), "clay");
  EXPECT_EQ(a.error().allowed_range(), "objects with materials");
  EXPECT_EQ(a.client_seq(), 6u);
  EXPECT_EQ(a.global_seq(), 0u);
}

}  // namespace
}  // namespace sculpt::server
