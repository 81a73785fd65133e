/// @brief Unit tests for DecodeUndo and the undo log record: undo and redo requests checked at the
/// edge, each refusal naming the field, the value and the allowed range.
#include "sculpt/codec/undo.h"

#include <gtest/gtest.h>

#include <string>

#include "sculpt/codec/log_records.h"
#include "sculpt/v1/sculpt.pb.h"
#include "unit/codec/field_violation.h"

namespace sculpt::codec {
namespace {

using testing::IsViolation;

v1::UndoRequest Valid() {
  v1::UndoRequest r;
  r.set_client_seq(9);
  r.set_object("clay");
  return r;
}

TEST(UndoRequestTest, DecodesAnUndo) {
  auto c = DecodeUndo(Valid());
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->client_seq, 9u);
  EXPECT_EQ(c->object, "clay");
  EXPECT_FALSE(c->redo);
}

TEST(UndoRequestTest, DecodesARedo) {
  v1::UndoRequest r = Valid();
  r.set_redo(true);
  auto c = DecodeUndo(r);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_TRUE(c->redo);
}

TEST(UndoRequestTest, AcceptsAnObjectNameOfTheMaximumLength) {
  v1::UndoRequest r = Valid();
  r.set_object(std::string(kMaxUndoObjectBytes, 'o'));
  EXPECT_TRUE(DecodeUndo(r).ok());
}

TEST(UndoRequestTest, RejectsEmptyObject) {
  v1::UndoRequest r = Valid();
  r.clear_object();
  EXPECT_TRUE(IsViolation(DecodeUndo(r).status(), "UndoRequest.object", "(0 bytes)",
                          "names of 1..64 bytes"));
}

TEST(UndoRequestTest, RejectsOverlongObjectWithoutEchoingIt) {
  v1::UndoRequest r = Valid();
  r.set_object(std::string(65, 'o'));
  const Status s = DecodeUndo(r).status();
  EXPECT_TRUE(IsViolation(s, "UndoRequest.object", "(65 bytes)", "names of 1..64 bytes"));
  EXPECT_EQ(s.message().find("ooooo"), std::string::npos) << s;
}

TEST(UndoRequestTest, RecordCarriesTheCommand) {
  v1::UndoRequest r = Valid();
  r.set_redo(true);
  auto c = DecodeUndo(r);
  ASSERT_TRUE(c.ok());
  UndoRecord rec;
  rec.global_seq = 41;
  rec.client_id = 7;
  rec.client_seq = c->client_seq;
  rec.object = c->object;
  rec.redo = c->redo;
  rec.author = "alice";
  auto back = DecodeLogRecord(41, EncodeLogRecord(rec));
  ASSERT_TRUE(back.ok()) << back.status();
  const auto* u = std::get_if<UndoRecord>(&*back);
  ASSERT_NE(u, nullptr);
  EXPECT_EQ(u->global_seq, 41u);
  EXPECT_EQ(u->client_id, 7u);
  EXPECT_EQ(u->author, "alice");
  EXPECT_EQ(u->client_seq, 9u);
  EXPECT_EQ(u->object, "clay");
  EXPECT_TRUE(u->redo);
}

}  // namespace
}  // namespace sculpt::codec
