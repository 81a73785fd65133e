#include "net/resend_allowance.h"

#include <gtest/gtest.h>

#include <limits>

namespace sculpt::server {
namespace {

v1::JoinScene Declaring(std::initializer_list<std::tuple<v1::EditStream, uint64_t, uint64_t>> rs) {
  v1::JoinScene j;
  for (const auto& [stream, first, last] : rs) {
    v1::ResendRange* r = j.add_resends();
    r->set_stream(stream);
    r->set_first_seq(first);
    r->set_last_seq(last);
  }
  return j;
}

class ResendAllowanceTest : public ::testing::Test {
 protected:
  static Status::Violation ViolationOf(const v1::JoinScene& j, uint64_t allowance) {
    auto r = ResendAllowance::Decode(j, allowance);
    EXPECT_FALSE(r.ok());
    if (r.ok() || !r.status().violation()) return {};
    return *r.status().violation();
  }
};

TEST_F(ResendAllowanceTest, AllowanceIsABurstAndFiveSecondsOfStrokes) {
  LimitsConfig limits;
  limits.stroke_burst = 60;
  limits.strokes_per_second = 240;
  EXPECT_EQ(ResendAllowance::AllowanceFor(limits), 60u + 5u * 240u);
  limits.stroke_burst = -1e9;
  EXPECT_EQ(ResendAllowance::AllowanceFor(limits), 0u);
}

TEST_F(ResendAllowanceTest, DeclaredRangesPassFreeOnceInIncreasingOrder) {
  auto ranges = ResendAllowance::Decode(
      Declaring({{v1::EDIT_STREAM_STROKES, 10, 20}, {v1::EDIT_STREAM_UNDOS, 15, 15}}), 100);
  ASSERT_TRUE(ranges.ok()) << ranges.status();
  ResendAllowance a;
  a.Declare(*ranges, 100);
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 9));  // below the range, nothing committed
  for (uint64_t s = 10; s <= 20; ++s) EXPECT_TRUE(a.Take(ResendStream::kStrokes, s)) << s;
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 20));  // once
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 21));  // a new stroke
  EXPECT_FALSE(a.Take(ResendStream::kPaints, 12));   // another stream, not declared
  EXPECT_TRUE(a.Take(ResendStream::kUndos, 15));
  EXPECT_EQ(a.left(), 100u - 12u);
}

TEST_F(ResendAllowanceTest, OutOfOrderResendsAreCharged) {
  auto ranges = ResendAllowance::Decode(Declaring({{v1::EDIT_STREAM_STROKES, 1, 10}}), 100);
  ASSERT_TRUE(ranges.ok());
  ResendAllowance a;
  a.Declare(*ranges, 100);
  EXPECT_TRUE(a.Take(ResendStream::kStrokes, 5));
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 3));
  EXPECT_TRUE(a.Take(ResendStream::kStrokes, 6));
}

TEST_F(ResendAllowanceTest, CommittedResendsPassWithoutADeclarationWithinTheAllowance) {
  ResendAllowance a;
  a.Declare({}, 3);
  std::array<uint64_t, kResendStreams> committed{};
  committed[static_cast<size_t>(ResendStream::kStrokes)] = 8;
  a.SetCommitted(committed);
  EXPECT_TRUE(a.Take(ResendStream::kStrokes, 1));
  EXPECT_TRUE(a.Take(ResendStream::kStrokes, 2));
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 9));  // not committed, not declared
  EXPECT_TRUE(a.Take(ResendStream::kStrokes, 3));
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 4));  // the allowance is spent
  EXPECT_EQ(a.left(), 0u);
}

TEST_F(ResendAllowanceTest, TheAllowanceBoundsDeclaredAndCommittedTogether) {
  auto ranges = ResendAllowance::Decode(Declaring({{v1::EDIT_STREAM_STROKES, 5, 8}}), 4);
  ASSERT_TRUE(ranges.ok());
  ResendAllowance a;
  a.Declare(*ranges, 4);
  std::array<uint64_t, kResendStreams> committed{};
  committed[static_cast<size_t>(ResendStream::kStrokes)] = 4;
  a.SetCommitted(committed);
  for (uint64_t s = 1; s <= 4; ++s) EXPECT_TRUE(a.Take(ResendStream::kStrokes, s));
  EXPECT_FALSE(a.Take(ResendStream::kStrokes, 5));  // declared, but the connection's 4 are used
}

TEST_F(ResendAllowanceTest, RejectsADeclarationLargerThanTheAllowance) {
  const auto v = ViolationOf(
      Declaring({{v1::EDIT_STREAM_STROKES, 1, 60}, {v1::EDIT_STREAM_PAINTS, 100, 141}}), 100);
  EXPECT_EQ(v.field, "JoinScene.resends");
  EXPECT_EQ(v.value, "102 client_seqs");
  EXPECT_EQ(v.allowed_range.rfind("[0, 100]", 0), 0u) << v.allowed_range;
  auto r = ResendAllowance::Decode(Declaring({{v1::EDIT_STREAM_STROKES, 1, 60}}), 100);
  ASSERT_TRUE(r.ok());
}

TEST_F(ResendAllowanceTest, RejectsARangeSpanningAllSequencesWithoutWrapping) {
  const uint64_t max = std::numeric_limits<uint64_t>::max();
  const auto v = ViolationOf(Declaring({{v1::EDIT_STREAM_STROKES, 1, max}}), 1000);
  EXPECT_EQ(v.field, "JoinScene.resends");
  auto r = ResendAllowance::Decode(
      Declaring({{v1::EDIT_STREAM_STROKES, 5, 4}, {v1::EDIT_STREAM_PAINTS, 1, max}}), 1000);
  ASSERT_FALSE(r.ok());
  ASSERT_TRUE(r.status().violation());
  EXPECT_EQ(r.status().violation()->field, "JoinScene.resends[0].last_seq");
}

TEST_F(ResendAllowanceTest, RejectsLastSeqBelowFirstSeq) {
  const auto v = ViolationOf(Declaring({{v1::EDIT_STREAM_STROKES, 10, 9}}), 100);
  EXPECT_EQ(v.field, "JoinScene.resends[0].last_seq");
  EXPECT_EQ(v.value, "9");
  EXPECT_EQ(v.allowed_range, "[first_seq=10, 2^64-1]");
}

TEST_F(ResendAllowanceTest, RejectsFirstSeqZero) {
  const auto v = ViolationOf(Declaring({{v1::EDIT_STREAM_STROKES, 0, 3}}), 100);
  EXPECT_EQ(v.field, "JoinScene.resends[0].first_seq");
}

TEST_F(ResendAllowanceTest, RejectsAStreamDeclaredTwice) {
  const auto v = ViolationOf(
      Declaring({{v1::EDIT_STREAM_STROKES, 1, 2}, {v1::EDIT_STREAM_STROKES, 5, 6}}), 100);
  EXPECT_EQ(v.field, "JoinScene.resends[1].stream");
  EXPECT_EQ(v.value, "EDIT_STREAM_STROKES");
}

TEST_F(ResendAllowanceTest, RejectsAnUnknownStream) {
  v1::JoinScene j = Declaring({{v1::EDIT_STREAM_UNSPECIFIED, 1, 2}});
  EXPECT_EQ(ViolationOf(j, 100).field, "JoinScene.resends[0].stream");
  j.mutable_resends(0)->set_stream(static_cast<v1::EditStream>(7));
  const auto v = ViolationOf(j, 100);
  EXPECT_EQ(v.field, "JoinScene.resends[0].stream");
  EXPECT_EQ(v.value, "7");
}

TEST_F(ResendAllowanceTest, RejectsMoreRangesThanStreams) {
  v1::JoinScene j;
  for (int i = 0; i < 7; ++i) j.add_resends();
  EXPECT_EQ(ViolationOf(j, 100).field, "JoinScene.resends");
}

}  // namespace
}  // namespace sculpt::server
