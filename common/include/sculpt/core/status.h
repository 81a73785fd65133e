/// @brief Status and StatusOr<T>: error values that name the field, the value and the allowed range.
#ifndef SCULPT_CORE_STATUS_H_
#define SCULPT_CORE_STATUS_H_

#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <variant>

namespace sculpt {

/// The outcome of an operation: ok, or a code with a human-readable message.
/// Thread safety: a value type; distinct instances may be used from different threads.
class Status {
 public:
  enum class Code {
    kOk = 0,
    kInvalidArgument,
    kOutOfRange,
    kNotFound,
    kFailedPrecondition,
    kResourceExhausted,
    kDataLoss,
    kUnavailable,
    kInternal,
  };

  Status() = default;
  Status(Code code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string ToString() const;

 private:
  Code code_ = Code::kOk;
  std::string message_;
};

const char* CodeName(Status::Code code);
std::ostream& operator<<(std::ostream& os, const Status& s);

inline Status InvalidArgument(std::string m) {
  return Status(Status::Code::kInvalidArgument, std::move(m));
}
inline Status OutOfRange(std::string m) { return Status(Status::Code::kOutOfRange, std::move(m)); }
inline Status NotFound(std::string m) { return Status(Status::Code::kNotFound, std::move(m)); }
inline Status FailedPrecondition(std::string m) {
  return Status(Status::Code::kFailedPrecondition, std::move(m));
}
inline Status ResourceExhausted(std::string m) {
  return Status(Status::Code::kResourceExhausted, std::move(m));
}
inline Status DataLoss(std::string m) { return Status(Status::Code::kDataLoss, std::move(m)); }
inline Status Internal(std::string m) { return Status(Status::Code::kInternal, std::move(m)); }

/// Either a value or a non-ok Status.
template <typename T>
class StatusOr {
 public:
  StatusOr(const Status& status) : status_(status) {  // NOLINT: implicit by design
    if (status_.ok()) status_ = Internal("StatusOr constructed from an ok Status without a value");
  }
  StatusOr(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design

  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  T&& value() && { return std::move(*value_); }
  const T& operator*() const& { return *value_; }
  T& operator*() & { return *value_; }
  const T* operator->() const { return &*value_; }
  T* operator->() { return &*value_; }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace sculpt

#define SCULPT_STATUS_CONCAT_INNER_(a, b) a##b
#define SCULPT_STATUS_CONCAT_(a, b) SCULPT_STATUS_CONCAT_INNER_(a, b)

/// Returns from the enclosing function if `expr` yields a non-ok Status.
#define SCULPT_RETURN_IF_ERROR(expr)                        \
  do {                                                      \
    ::sculpt::Status sculpt_status_tmp_ = (expr);           \
    if (!sculpt_status_tmp_.ok()) return sculpt_status_tmp_; \
  } while (0)

/// Declares `lhs` from a StatusOr expression, or returns its error.
#define SCULPT_ASSIGN_OR_RETURN(lhs, expr)                                       \
  auto SCULPT_STATUS_CONCAT_(sculpt_statusor_, __LINE__) = (expr);               \
  if (!SCULPT_STATUS_CONCAT_(sculpt_statusor_, __LINE__).ok())                   \
    return SCULPT_STATUS_CONCAT_(sculpt_statusor_, __LINE__).status();           \
  lhs = std::move(SCULPT_STATUS_CONCAT_(sculpt_statusor_, __LINE__)).value()

#endif  // SCULPT_CORE_STATUS_H_
