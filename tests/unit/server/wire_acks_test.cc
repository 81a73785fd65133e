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
  SkinOutcome o{Outside("SkinSweep.skin", "nope", "the scene's skins", Status::Code::kNotFound), 9};
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
  SkinOutcome o{Outside("SkinBallEdit.index", "9", "[0, 4]"), 3};
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
      ToWireAck(PaintOutcome{Outside("PaintEdit.object", "clay", "objects with materials",
                                     Status::Code::kFailedPrecondition),
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
  o.status = Outside("ModelIntent", "SKIN_INTERSECT", "intents that keep the model valid",
                     Status::Code::kFailedPrecondition);
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
  o.status = Outside("ModelIntent.corner", "99", "[0, 15]");
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

TEST(WireAcksTest, UndoAckOfAnAcceptedUndo) {
  UndoCommandOutcome o;
  o.client_seq = 4;
  o.redo = true;
  o.global_seq = 90;
  o.target_seq = 71;
  o.replayed = 3;
  o.replayed_by = {{"11", 1}, {"22", 2}};
  o.undo_depth = 5;
  o.redo_depth = 1;
  const v1::UndoAck a = ToWireAck(o);
  EXPECT_TRUE(a.accepted());
  EXPECT_FALSE(a.has_error());
  EXPECT_TRUE(a.redo());
  EXPECT_EQ(a.client_seq(), 4u);
  EXPECT_EQ(a.global_seq(), 90u);
  EXPECT_EQ(a.target_seq(), 71u);
  EXPECT_EQ(a.replayed(), 3u);
  ASSERT_EQ(a.replayed_by_size(), 2);
  EXPECT_EQ(a.replayed_by(0).author(), "11");
  EXPECT_EQ(a.replayed_by(1).edits(), 2u);
  EXPECT_EQ(a.undo_depth(), 5u);
  EXPECT_EQ(a.redo_depth(), 1u);
}

TEST(WireAcksTest, UndoAckOfADuplicateSendsNoDetails) {
  UndoCommandOutcome o;
  o.client_seq = 4;
  o.duplicate = true;
  o.global_seq = 90;  // not reported for a duplicate
  o.target_seq = 71;
  v1::UndoAck expected;
  expected.set_client_seq(4);
  expected.set_accepted(true);
  expected.set_duplicate(true);
  EXPECT_EQ(ToWireAck(o).SerializeAsString(), expected.SerializeAsString());
}

TEST(WireAcksTest, UndoAckOfARefusalCarriesTheErrorAndTheLoggedSequence) {
  UndoCommandOutcome o;
  o.status = Outside("UndoRequest.redo", "true", "requests with an undone stroke",
                     Status::Code::kFailedPrecondition);
  o.client_seq = 6;
  o.redo = true;
  o.global_seq = 33;  // refused after it was logged
  o.target_seq = 5;   // not reported for a refusal
  const v1::UndoAck a = ToWireAck(o);
  EXPECT_FALSE(a.accepted());
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().code(), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(a.error().field(), "UndoRequest.redo");
  EXPECT_EQ(a.error().value(), "true");
  EXPECT_EQ(a.error().client_seq(), 6u);
  EXPECT_TRUE(a.redo());
  EXPECT_EQ(a.global_seq(), 33u);
  EXPECT_EQ(a.target_seq(), 0u);
}

TEST(WireAcksTest, HistoryAnswerCarriesEntriesInOrder) {
  HistoryOutcome o;
  o.request_id = 12;
  o.object = "clay";
  o.matching = 7;
  o.held = 9;
  o.cleared = "a sweep";
  HistoryEntry newest;
  newest.seq = 40;
  newest.author = "11";
  newest.kind = levelset::EditKind::kAdd;
  newest.poses = 3;
  newest.undoable = true;
  newest.wall_ms = 1234;
  HistoryEntry older;
  older.seq = 20;
  older.sweep = true;
  older.undone = true;
  o.entries = {newest, older};
  const v1::HistoryAnswer a = ToWireAnswer(o);
  EXPECT_FALSE(a.has_error());
  EXPECT_EQ(a.request_id(), 12u);
  EXPECT_EQ(a.object(), "clay");
  EXPECT_EQ(a.matching(), 7u);
  EXPECT_EQ(a.held(), 9u);
  EXPECT_EQ(a.cleared(), "a sweep");
  ASSERT_EQ(a.entries_size(), 2);
  EXPECT_EQ(a.entries(0).seq(), 40u);
  EXPECT_EQ(a.entries(0).author(), "11");
  EXPECT_EQ(a.entries(0).kind(), v1::EDIT_KIND_ADD);
  EXPECT_EQ(a.entries(0).poses(), 3u);
  EXPECT_TRUE(a.entries(0).undoable());
  EXPECT_EQ(a.entries(0).time_ms(), 1234u);
  EXPECT_EQ(a.entries(1).seq(), 20u);
  EXPECT_TRUE(a.entries(1).sweep());
  EXPECT_TRUE(a.entries(1).undone());
}

TEST(WireAcksTest, HistoryAnswerOfARefusalCarriesOnlyTheError) {
  HistoryOutcome o;
  o.status = Outside("HistoryRequest.object", "marble", "the scene's objects",
                     Status::Code::kNotFound);
  o.request_id = 3;
  o.object = "marble";
  o.held = 5;  // not reported for a refusal
  const v1::HistoryAnswer a = ToWireAnswer(o);
  ASSERT_TRUE(a.has_error());
  EXPECT_EQ(a.error().code(), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(a.error().field(), "HistoryRequest.object");
  EXPECT_EQ(a.error().value(), "marble");
  EXPECT_EQ(a.error().client_seq(), 0u);
  EXPECT_EQ(a.request_id(), 3u);
  EXPECT_EQ(a.object(), "marble");
  EXPECT_EQ(a.held(), 0u);
  EXPECT_EQ(a.entries_size(), 0);
}

}  // namespace
}  // namespace sculpt::server
