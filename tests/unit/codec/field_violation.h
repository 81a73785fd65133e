/// @brief A test helper: asserts that a refusal names the field, the value and the allowed range.
#ifndef SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_
#define SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_

#include <gtest/gtest.h>

#include <string>

#include "sculpt/codec/stroke.h"
#include "sculpt/core/status.h"

namespace sculpt::codec::testing {

/// Success when `status` has `code` and its message reads `field=value outside range` (or
/// `field=value is not finite`, whose range is "finite numbers").
inline ::testing::AssertionResult IsViolation(const Status& status, const std::string& field,
                                              const std::string& value, const std::string& range,
                                              Status::Code code = Status::Code::kInvalidArgument) {
  if (status.code() != code) {
    return ::testing::AssertionFailure() << "code " << CodeName(status.code()) << ", wanted "
                                         << CodeName(code) << ": " << status;
  }
  const FieldError fe = SplitFieldError(status);
  if (fe.field != field || fe.value != value || fe.allowed_range != range) {
    return ::testing::AssertionFailure()
           << "field [" << fe.field << "] value [" << fe.value << "] range [" << fe.allowed_range
           << "], wanted [" << field << "] [" << value << "] [" << range << "]";
  }
  return ::testing::AssertionSuccess();
}

}  // namespace sculpt::codec::testing

#endif  // SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_
