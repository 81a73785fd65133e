#include "sculpt/core/status.h"

#include <gtest/gtest.h>

namespace sculpt {
namespace {

StatusOr<int> Half(int v) {
  if (v % 2 != 0) return InvalidArgument("v=" + std::to_string(v) + " outside even integers");
  return v / 2;
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
