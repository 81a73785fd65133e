/// @brief Unit tests for DecodeHistoryRequest: the history view's request checked at the edge,
/// each refusal naming the field, the value and the allowed range.
#include "sculpt/codec/history.h"

#include <gtest/gtest.h>

#include <string>

#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

v1::HistoryRequest Valid() {
  v1::HistoryRequest r;
  r.set_request_id(7);
  r.set_object("clay");
  r.set_author("515151");
  r.set_limit(10);
  return r;
}

void ExpectRefused(const v1::HistoryRequest& r, const std::string& field,
                   const std::string& range_part) {
  auto q = DecodeHistoryRequest(r);
  ASSERT_FALSE(q.ok());
  EXPECT_EQ(q.status().code(), Status::Code::kInvalidArgument);
  const Status::Violation* e = q.status().violation();
  ASSERT_NE(e, nullptr) << q.status();
  EXPECT_EQ(e->field, field) << q.status().message();
  EXPECT_FALSE(e->value.empty()) << q.status().message();
  EXPECT_NE(e->allowed_range.find(range_part), std::string::npos) << q.status().message();
}

TEST(HistoryRequestTest, DecodesAValidRequest) {
  auto q = DecodeHistoryRequest(Valid());
  ASSERT_TRUE(q.ok()) << q.status();
  EXPECT_EQ(q->request_id, 7u);
  EXPECT_EQ(q->object, "clay");
  EXPECT_EQ(q->author, "515151");
  EXPECT_EQ(q->limit, 10u);
}

TEST(HistoryRequestTest, ZeroLimitTakesTheDefaultAndEmptyAuthorMeansEveryone) {
  v1::HistoryRequest r = Valid();
  r.set_limit(0);
  r.clear_author();
  auto q = DecodeHistoryRequest(r);
  ASSERT_TRUE(q.ok()) << q.status();
  EXPECT_EQ(q->limit, kDefaultHistoryLimit);
  EXPECT_TRUE(q->author.empty());
  r.set_limit(kMaxHistoryLimit);
  EXPECT_TRUE(DecodeHistoryRequest(r).ok());
}

TEST(HistoryRequestTest, RejectsLimitAboveTheMaximum) {
  v1::HistoryRequest r = Valid();
  r.set_limit(kMaxHistoryLimit + 1);
  ExpectRefused(r, "HistoryRequest.limit", "[0, 1000]");
  r.set_limit(UINT32_MAX);
  ExpectRefused(r, "HistoryRequest.limit", "[0, 1000]");
}

TEST(HistoryRequestTest, RejectsEmptyOrOverlongObject) {
  v1::HistoryRequest r = Valid();
  r.clear_object();
  ExpectRefused(r, "HistoryRequest.object", "1..64 bytes");
  r.set_object(std::string(65, 'o'));
  ExpectRefused(r, "HistoryRequest.object", "1..64 bytes");
}

TEST(HistoryRequestTest, RejectsOverlongAuthor) {
  v1::HistoryRequest r = Valid();
  r.set_author(std::string(65, 'a'));
  ExpectRefused(r, "HistoryRequest.author", "0..64 bytes");
}

TEST(HistoryRequestTest, RejectsControlCharactersInAuthor) {
  v1::HistoryRequest r = Valid();
  r.set_author(std::string("al\nice"));
  ExpectRefused(r, "HistoryRequest.author", "without control characters");
  r.set_author(std::string("a\0b", 3));
  ExpectRefused(r, "HistoryRequest.author", "without control characters");
}

}  // namespace
}  // namespace sculpt::codec
