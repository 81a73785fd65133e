/// @brief A test helper: asserts that a refusal names the field, the value and the allowed range.
#ifndef SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_
#define SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_

#include <gtest/gtest.h>

#include <string>

#include "sculpt/core/status.h"

namespace sculpt::codec::testing {

/// Success when `status` has `code` and carries the violation (`field`, `value`, `range`), and its
/// message names the field (a not-finite value's range is "finite numbers").
inline ::testing::AssertionResult IsViolation(const Status& status, const std::string& field,
                                              const std::string& value, const std::string& range,
                                              Status::Code code = Status::Code::kInvalidArgument) {
  if (status.code() != code) {
    return ::testing::AssertionFailure() << "code " << CodeName(status.code()) << ", wanted "
                                         << CodeName(code) << ": " << status;
  }
  const Status::Violation* fe = status.violation();
  if (fe == nullptr) {
    return ::testing::AssertionFailure() << "no field violation in " << status;
  }
  if (fe->field != field || fe->value != value || fe->allowed_range != range) {
    return ::testing::AssertionFailure()
           << "field [" << fe->field << "] value [" << fe->value << "] range ["
           << fe->allowed_range << "], wanted [" << field << "] [" << value << "] [" << range
           << "]";
  }
  if (status.message().find(field) == std::string::npos) {
    return ::testing::AssertionFailure() << "the message does not name " << field << ": " << status;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace sculpt::codec::testing

#endif  // SCULPT_TESTS_UNIT_CODEC_FIELD_VIOLATION_H_
