/// @brief Status → sculpt.v1.Error.
#include "net/wire_error.h"

#include "net/untrusted_text.h"

namespace sculpt::server {

v1::ErrorCode ToWireCode(Status::Code code) {
  switch (code) {
    case Status::Code::kInvalidArgument:
    case Status::Code::kOutOfRange: return v1::ERROR_CODE_INVALID_ARGUMENT;
    case Status::Code::kNotFound: return v1::ERROR_CODE_NOT_FOUND;
    case Status::Code::kFailedPrecondition: return v1::ERROR_CODE_FAILED_PRECONDITION;
    case Status::Code::kResourceExhausted: return v1::ERROR_CODE_RESOURCE_EXHAUSTED;
    case Status::Code::kUnavailable: return v1::ERROR_CODE_UNAVAILABLE;  // cluster: not owner now
    case Status::Code::kOk:
    case Status::Code::kDataLoss:
    case Status::Code::kInternal: return v1::ERROR_CODE_INTERNAL;
  }
  return v1::ERROR_CODE_INTERNAL;
}

v1::Error ToWireError(const Status& status, uint64_t client_seq) {
  // The violation was set where the error was made; an error naming no field sends only its
  // message.
  const Status::Violation* v = status.violation();
  if (v == nullptr) {
    return ProtocolError(ToWireCode(status.code()), "", "", "", status.message(), client_seq);
  }
  return ProtocolError(ToWireCode(status.code()), v->field, v->value, v->allowed_range,
                       status.message(), client_seq);
}

v1::Error ProtocolError(v1::ErrorCode code, std::string field, std::string value,
                        std::string allowed_range, std::string message, uint64_t client_seq) {
  // Any of these may quote a client's text (a name, an object, a scene): bounded and escaped
  // here, once for every error, so nothing a client sends is echoed back at length.
  v1::Error e;
  e.set_code(code);
  e.set_field(Printable(field, kMaxErrorFieldBytes));
  e.set_value(Printable(value, kMaxErrorFieldBytes));
  e.set_allowed_range(Printable(allowed_range, kMaxErrorTextBytes));
  e.set_message(Printable(message, kMaxErrorTextBytes));
  e.set_client_seq(client_seq);
  return e;
}

}  // namespace sculpt::server
