#include "net/wire_error.h"

#include <gtest/gtest.h>

namespace sculpt::server {
namespace {

TEST(WireErrorTest, MapsEveryStatusCode) {
  EXPECT_EQ(ToWireCode(Status::Code::kInvalidArgument), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(ToWireCode(Status::Code::kOutOfRange), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(ToWireCode(Status::Code::kNotFound), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(ToWireCode(Status::Code::kFailedPrecondition), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(ToWireCode(Status::Code::kResourceExhausted), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(ToWireCode(Status::Code::kDataLoss), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(ToWireCode(Status::Code::kUnavailable), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(ToWireCode(Status::Code::kInternal), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(ToWireCode(Status::Code::kOk), v1::ERROR_CODE_INTERNAL);
}

TEST(WireErrorTest, CarriesFieldValueRangeAndSequence) {
  const v1::Error e = ToWireError(InvalidArgument("Stroke.radius=0 outside (0, 64] voxels"), 17);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(e.field(), "Stroke.radius");
  EXPECT_EQ(e.value(), "0");
  EXPECT_EQ(e.allowed_range(), "(0, 64] voxels");
  EXPECT_EQ(e.client_seq(), 17u);
  EXPECT_FALSE(e.message().empty());
}

TEST(WireErrorTest, KeepsAMessageWithoutAField) {
  const v1::Error e = ToWireError(Internal("disk on fire"));
  EXPECT_EQ(e.code(), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(e.field(), "");
  EXPECT_EQ(e.message(), "disk on fire");
  EXPECT_EQ(e.client_seq(), 0u);
}

TEST(WireErrorTest, ProtocolErrorSetsEveryField) {
  const v1::Error e = ProtocolError(v1::ERROR_CODE_UNAUTHENTICATED, "Hello.token", "(hidden)",
                                    "the configured token", "wrong token", 3);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_UNAUTHENTICATED);
  EXPECT_EQ(e.field(), "Hello.token");
  EXPECT_EQ(e.value(), "(hidden)");
  EXPECT_EQ(e.allowed_range(), "the configured token");
  EXPECT_EQ(e.message(), "wrong token");
  EXPECT_EQ(e.client_seq(), 3u);
}

}  // namespace
}  // namespace sculpt::server
