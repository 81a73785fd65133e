/// @brief Status and StatusOr<T>: error values that name the field, the value and the allowed range.
#ifndef SCULPT_CORE_STATUS_H_
#define SCULPT_CORE_STATUS_H_

#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <variant>

namespace sculpt {

/// The outcome of an operation: ok, or a code with a human-readable message and, for a refused
/// value, the structured field violation (the field, its value and the allowed range, as gRPC's
/// BadRequest.FieldViolation) set where the error is made, so the wire error is filled from data
/// rather than from the message's text.
/// An ok Status holds no allocation; an error shares its immutable detail between copies, so
/// copying and returning a Status costs a code and a reference count.
/// Thread safety: a value type; distinct instances may be used from different threads, and copies
/// of one error may be read from several threads.
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

  /// What a refusal names: `field` (e.g. "Stroke.tool_size.x"), the `value` it had as text and the
  /// `allowed_range` ("[0.5, 64]", "finite numbers", "an existing object"; empty if none applies).
  struct Violation {
    std::string field;
    std::string value;
    std::string allowed_range;
  };

  Status() = default;
  Status(Code code, std::string message);
  Status(Code code, std::string message, Violation violation);

  static Status Ok() { return Status(); }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  /// The message; empty when ok.
  const std::string& message() const;
  /// The field violation, or null when the error names no field (and when ok).
  const Violation* violation() const {
    return detail_ && detail_->violation ? &*detail_->violation : nullptr;
  }
  std::string ToString() const;

 private:
  // One allocation per error, shared by its copies.
  struct Detail {
    std::string message;
    std::optional<Violation> violation;
  };

  Code code_ = Code::kOk;
  std::shared_ptr<const Detail> detail_;
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

/// An error naming the refused field: `code` and `message` as above, with the violation's field,
/// value and allowed range carried as data.
inline Status FieldViolation(Status::Code code, std::string field, std::string value,
                             std::string allowed_range, std::string message) {
  return Status(code, std::move(message),
                Status::Violation{std::move(field), std::move(value), std::move(allowed_range)});
}

/// The common refusal: `code` (InvalidArgument unless given) with the message
/// "`field`=`value` outside `allowed_range`" and that violation.
Status Outside(std::string field, std::string value, std::string allowed_range,
               Status::Code code = Status::Code::kInvalidArgument);

/// InvalidArgument "`field`=`value` is not finite", whose allowed range is "finite numbers".
Status NotFinite(std::string field, std::string value);

/// The same error (code and violation kept) with its message read "`context`: message", for a
/// caller that says where a part's error arose. An ok `status` is returned unchanged.
Status WithContext(const Status& status, const std::string& context);

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
