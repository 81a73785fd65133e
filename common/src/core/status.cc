/// @brief Status formatting and the field-violation factories.
#include "sculpt/core/status.h"

#include "sculpt/core/concat.h"

namespace sculpt {

std::string Concat(std::initializer_list<std::string_view> parts) {
  size_t size = 0;
  for (std::string_view part : parts) size += part.size();
  std::string out;
  out.reserve(size);
  for (std::string_view part : parts) out.append(part);
  return out;
}

Status::Status(Code code, std::string message) : code_(code) {
  if (code_ != Code::kOk) {
    detail_ = std::make_shared<const Detail>(Detail{std::move(message), std::nullopt});
  }
}

Status::Status(Code code, std::string message, Violation violation) : code_(code) {
  if (code_ != Code::kOk) {
    detail_ = std::make_shared<const Detail>(Detail{std::move(message), std::move(violation)});
  }
}

const std::string& Status::message() const {
  static const std::string kEmpty;
  return detail_ ? detail_->message : kEmpty;
}

const char* CodeName(Status::Code code) {
  switch (code) {
    case Status::Code::kOk: return "OK";
    case Status::Code::kInvalidArgument: return "INVALID_ARGUMENT";
    case Status::Code::kOutOfRange: return "OUT_OF_RANGE";
    case Status::Code::kNotFound: return "NOT_FOUND";
    case Status::Code::kFailedPrecondition: return "FAILED_PRECONDITION";
    case Status::Code::kResourceExhausted: return "RESOURCE_EXHAUSTED";
    case Status::Code::kDataLoss: return "DATA_LOSS";
    case Status::Code::kUnavailable: return "UNAVAILABLE";
    case Status::Code::kInternal: return "INTERNAL";
  }
  return "UNKNOWN";
}

std::string Status::ToString() const {
  if (ok()) return "OK";
  return Concat({CodeName(code_), ": ", message()});
}

std::ostream& operator<<(std::ostream& os, const Status& s) { return os << s.ToString(); }

Status Outside(std::string field, std::string value, std::string allowed_range,
               Status::Code code) {
  std::string message = Concat({field, "=", value, " outside ", allowed_range});
  return FieldViolation(code, std::move(field), std::move(value), std::move(allowed_range),
                        std::move(message));
}

Status NotFinite(std::string field, std::string value) {
  std::string message = Concat({field, "=", value, " is not finite"});
  return FieldViolation(Status::Code::kInvalidArgument, std::move(field), std::move(value),
                        "finite numbers", std::move(message));
}

Status WithContext(const Status& status, const std::string& context) {
  if (status.ok()) return status;
  std::string message = Concat({context, ": ", status.message()});
  if (const Status::Violation* v = status.violation()) {
    return Status(status.code(), std::move(message), *v);
  }
  return Status(status.code(), std::move(message));
}

}  // namespace sculpt
