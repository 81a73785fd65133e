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

TEST(WireAcksTest, ModelAckOfAValidityRefusalCarriesTheReasonAndNoError) {
  ModelOutcome o;
  o.status = FailedPrecondition("ModelIntent=SKIN_INTERSECT outside intents that keep the model "
                                "valid");
  o.client_seq = 8;
  o.rejection = ModelRejection{"SKIN_INTERSECT", 1, -1, -1, "slices 2 and 3 cross"};
  o.model_version = 4;
  o.model_hash = 0xabcdef;
  const v1::ModelAck a = ToWireAck(o);
  EXPECT_FALSE(a.accepted());
  EXPECT_FALSE(a.has_error());
  EXPECT_EQ(a.reason(), "SKIN_INTERSECT");
  EXPECT_EQ(a.cell(), 1);
  EXPECT_EQ(a.direction(), -1);
  EXPECT_EQ(a.span(), -1);
  EXPECT_EQ(a.detail(), "slices 2 and 3 cross");
  EXPECT_EQ(a.model_version(), 4u);
  EXPECT_EQ(a.model_hash(), 0xabcdefu);
  EXPECT_EQ(a.global_seq(), 0u);
}

TEST(WireAcksTest, ModelAckOfAFieldRefusalCarriesTheError) {
  ModelOutcome o;
  o.status = InvalidArgument("ModelIntent.corner=99 outside [0, 15]");
  o.client_seq = 2;
  const v1::ModelAck a = ToWireAck(o);
  EXPECT_FALSE(a.accepted());
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().field(), "ModelIntent.corner");
  EXPECT_EQ(a.error().value(), "99");
  EXPECT_EQ(a.error().allowed_range(), "[0, 15]");
  EXPECT_TRUE(a.reason().empty());
}

TEST(WireAcksTest, ModelAckOfAnAcceptedIntent) {
  ModelOutcome o;
  o.client_seq = 1;
  o.global_seq = 50;
  o.moved_coefficients = 12;
  o.model_version = 2;
  o.model_hash = 99;
  const v1::ModelAck a = ToWireAck(o);
  EXPECT_TRUE(a.accepted());
  EXPECT_EQ(a.global_seq(), 50u);
  EXPECT_EQ(a.moved_coefficients(), 12u);
  EXPECT_EQ(a.model_version(), 2u);
  EXPECT_EQ(a.model_hash(), 99u);
}

}  // namespace
}  // namespace sculpt::server
