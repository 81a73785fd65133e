#include "sculpt/core/status.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>

namespace sculpt {
namespace {

StatusOr<int> Half(int v) {
  if (v % 2 != 0) return InvalidArgument("v=" + std::to_string(v) + " outside even integers");
  return v / 2;
}

Status Refuse() { return Outside("Stroke.speed", "-1", "[0, 64]"); }

Status PassOn() {
  SCULPT_RETURN_IF_ERROR(Refuse());
  return Status::Ok();
}

StatusOr<int> RefuseValue() { return Refuse(); }

Status AssignFrom() {
  SCULPT_ASSIGN_OR_RETURN(int v, RefuseValue());
  (void)v;
  return Status::Ok();
}

void ExpectSpeedViolation(const Status& s) {
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  ASSERT_NE(s.violation(), nullptr) << s;
  EXPECT_EQ(s.violation()->field, "Stroke.speed");
  EXPECT_EQ(s.violation()->value, "-1");
  EXPECT_EQ(s.violation()->allowed_range, "[0, 64]");
}

Status UseHalf(int v, int* out) {
  SCULPT_ASSIGN_OR_RETURN(int h, Half(v));
  *out = h;
  return Status::Ok();
}

TEST(StatusTest, OkByDefault) {
  Status s;
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(s.ToString(), "OK");
}

TEST(StatusTest, CarriesCodeAndMessage) {
  Status s = InvalidArgument("tool.size.x=-1 outside [0.5, 64]");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(s.ToString(), "INVALID_ARGUMENT: tool.size.x=-1 outside [0.5, 64]");
}

TEST(StatusTest, StatusOrPropagatesErrors) {
  int out = -1;
  EXPECT_TRUE(UseHalf(4, &out).ok());
  EXPECT_EQ(out, 2);
  Status s = UseHalf(3, &out);
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(out, 2);
}

TEST(StatusTest, StatusOrFromOkStatusIsAnError) {
  StatusOr<int> v(Status::Ok());
  EXPECT_FALSE(v.ok());
}

}  // namespace
}  // namespace sculpt

namespace sculpt {
namespace {

TEST(StatusViolationTest, OutsideFormatsTheMessageAndKeepsTheParts) {
  const Status s = Refuse();
  ExpectSpeedViolation(s);
  EXPECT_EQ(s.message(), "Stroke.speed=-1 outside [0, 64]");
  EXPECT_EQ(s.ToString(), "INVALID_ARGUMENT: Stroke.speed=-1 outside [0, 64]");
}

TEST(StatusViolationTest, OutsideTakesAnyCode) {
  const Status s = Outside("frame length", "5", "[0, 4]", Status::Code::kResourceExhausted);
  EXPECT_EQ(s.code(), Status::Code::kResourceExhausted);
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "frame length");
  EXPECT_EQ(s.message(), "frame length=5 outside [0, 4]");
}

TEST(StatusViolationTest, NotFiniteRangeIsFiniteNumbers) {
  const Status s = NotFinite("edit.speed", "inf");
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "edit.speed");
  EXPECT_EQ(s.violation()->value, "inf");
  EXPECT_EQ(s.violation()->allowed_range, "finite numbers");
  EXPECT_EQ(s.message(), "edit.speed=inf is not finite");
}

TEST(StatusViolationTest, FieldViolationKeepsTheGivenMessage) {
  const Status s = FieldViolation(Status::Code::kFailedPrecondition, "UndoRequest.redo", "true",
                                  "requests with an undone stroke", "nothing to redo");
  EXPECT_EQ(s.code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(s.message(), "nothing to redo");
  ASSERT_NE(s.violation(), nullptr);
  EXPECT_EQ(s.violation()->field, "UndoRequest.redo");
  EXPECT_EQ(s.violation()->value, "true");
}

TEST(StatusViolationTest, PlainErrorsAndOkNameNoField) {
  // A message that merely looks like `field=value` is not parsed: only the factories set a field.
  EXPECT_EQ(InvalidArgument("region=x outside y").violation(), nullptr);
  EXPECT_EQ(Status::Ok().violation(), nullptr);
  EXPECT_EQ(Status::Ok().message(), "");
  // An ok code given a violation stays a plain ok.
  const Status ok(Status::Code::kOk, "ignored", Status::Violation{"f", "v", "r"});
  EXPECT_TRUE(ok.ok());
  EXPECT_EQ(ok.violation(), nullptr);
}

TEST(StatusViolationTest, SurvivesCopyAndMove) {
  const Status original = Refuse();
  Status copy = original;  // NOLINT(performance-unnecessary-copy-initialization): the copy path
  ExpectSpeedViolation(copy);
  Status assigned;
  assigned = copy;
  ExpectSpeedViolation(assigned);
  Status moved = std::move(copy);
  ExpectSpeedViolation(moved);
  Status move_assigned;
  move_assigned = std::move(moved);
  ExpectSpeedViolation(move_assigned);
  ExpectSpeedViolation(original);
  // Copies share the one immutable detail rather than copying three strings.
  EXPECT_EQ(original.violation(), assigned.violation());
}

TEST(StatusViolationTest, SurvivesReturnIfErrorAndStatusOr) {
  ExpectSpeedViolation(PassOn());
  ExpectSpeedViolation(RefuseValue().status());
  ExpectSpeedViolation(AssignFrom());
}

TEST(StatusViolationTest, WithContextKeepsCodeAndViolation) {
  const Status s = WithContext(Refuse(), "replaying seq 7");
  ExpectSpeedViolation(s);
  EXPECT_EQ(s.message(), "replaying seq 7: Stroke.speed=-1 outside [0, 64]");
  const Status plain = WithContext(DataLoss("torn"), "segment 3");
  EXPECT_EQ(plain.code(), Status::Code::kDataLoss);
  EXPECT_EQ(plain.message(), "segment 3: torn");
  EXPECT_EQ(plain.violation(), nullptr);
  EXPECT_TRUE(WithContext(Status::Ok(), "x").ok());
}

TEST(StatusViolationTest, OkStatusIsSmallAndAllocatesNothing) {
  // A code and one shared pointer: returning Ok copies no strings.
  EXPECT_LE(sizeof(Status), sizeof(void*) * 3);
}

}  // namespace
}  // namespace sculpt
