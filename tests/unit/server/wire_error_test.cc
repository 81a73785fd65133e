#include "net/wire_error.h"

#include <gtest/gtest.h>

#include <string>

namespace sculpt::server {
namespace {

TEST(WireErrorTest, MapsEveryStatusCode) {
  EXPECT_EQ(ToWireCode(Status::Code::kInvalidArgument), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(ToWireCode(Status::Code::kOutOfRange), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(ToWireCode(Status::Code::kNotFound), v1::ERROR_CODE_NOT_FOUND);
  EXPECT_EQ(ToWireCode(Status::Code::kFailedPrecondition), v1::ERROR_CODE_FAILED_PRECONDITION);
  EXPECT_EQ(ToWireCode(Status::Code::kResourceExhausted), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_EQ(ToWireCode(Status::Code::kDataLoss), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(ToWireCode(Status::Code::kUnavailable), v1::ERROR_CODE_UNAVAILABLE);
  EXPECT_EQ(ToWireCode(Status::Code::kInternal), v1::ERROR_CODE_INTERNAL);
  EXPECT_EQ(ToWireCode(Status::Code::kOk), v1::ERROR_CODE_INTERNAL);
}

TEST(WireErrorTest, CarriesFieldValueRangeAndSequence) {
  const v1::Error e = ToWireError(Outside("Stroke.radius", "0", "(0, 64] voxels"), 17);
  EXPECT_EQ(e.code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(e.field(), "Stroke.radius");
  EXPECT_EQ(e.value(), "0");
  EXPECT_EQ(e.allowed_range(), "(0, 64] voxels");
  EXPECT_EQ(e.message(), "Stroke.radius=0 outside (0, 64] voxels");
  EXPECT_EQ(e.client_seq(), 17u);
}

TEST(WireErrorTest, FillsTheViolationForEveryCode) {
  // The structure travels whatever the code; the message is the Status's own.
  for (const Status::Code code :
       {Status::Code::kInvalidArgument, Status::Code::kOutOfRange, Status::Code::kNotFound,
        Status::Code::kFailedPrecondition, Status::Code::kResourceExhausted,
        Status::Code::kDataLoss, Status::Code::kUnavailable, Status::Code::kInternal}) {
    const v1::Error e = ToWireError(
        FieldViolation(code, "Undo.object", "vase", "the scene's objects", "no vase here"), 5);
    EXPECT_EQ(e.code(), ToWireCode(code)) << CodeName(code);
    EXPECT_EQ(e.field(), "Undo.object") << CodeName(code);
    EXPECT_EQ(e.value(), "vase") << CodeName(code);
    EXPECT_EQ(e.allowed_range(), "the scene's objects") << CodeName(code);
    EXPECT_EQ(e.message(), "no vase here") << CodeName(code);
    EXPECT_EQ(e.client_seq(), 5u) << CodeName(code);
  }
}

TEST(WireErrorTest, NotFiniteSendsFiniteNumbersAsTheRange) {
  const v1::Error e = ToWireError(NotFinite("Stroke.speed", "nan"));
  EXPECT_EQ(e.field(), "Stroke.speed");
  EXPECT_EQ(e.value(), "nan");
  EXPECT_EQ(e.allowed_range(), "finite numbers");
}

TEST(WireErrorTest, DoesNotParseTheMessage) {
  // Only a violation set where the error was made names a field; text that merely looks like
  // one stays message.
  const v1::Error e = ToWireError(InvalidArgument("Stroke.radius=0 outside (0, 64] voxels"));
  EXPECT_EQ(e.field(), "");
  EXPECT_EQ(e.value(), "");
  EXPECT_EQ(e.allowed_range(), "");
  EXPECT_EQ(e.message(), "Stroke.radius=0 outside (0, 64] voxels");
}

TEST(WireErrorTest, BoundsAndEscapesAClientsValue) {
  const v1::Error e =
      ToWireError(Outside("Stroke.object", std::string(1000, 'x') + "\x01", "names"));
  EXPECT_LE(e.value().size(), kMaxErrorFieldBytes + 24);
  EXPECT_EQ(e.value().find('\x01'), std::string::npos);
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
