/// @brief The one mapping from a Status to the wire's sculpt.v1.Error, and the builder of the
/// session's protocol errors (the codes a Status has no name for).
#ifndef SCULPT_SERVER_NET_WIRE_ERROR_H_
#define SCULPT_SERVER_NET_WIRE_ERROR_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

/// The wire code of a Status code: InvalidArgument and OutOfRange → INVALID_ARGUMENT, NotFound →
/// NOT_FOUND, FailedPrecondition → FAILED_PRECONDITION, ResourceExhausted → RESOURCE_EXHAUSTED,
/// DataLoss, Unavailable and Internal → INTERNAL. An ok Status maps to INTERNAL (a caller bug
/// reported rather than hidden).
v1::ErrorCode ToWireCode(Status::Code code);

/// A refusal as a wire Error: the code above, the Status's field violation (field, value, allowed
/// range; empty when it has none) and its message, for the message with sequence number
/// `client_seq` (0 when none).
v1::Error ToWireError(const Status& status, uint64_t client_seq = 0);

/// Bounds of an Error's strings: field and value, allowed range and message (net/untrusted_text.h
/// escapes and cuts them).
inline constexpr size_t kMaxErrorFieldBytes = 128;
inline constexpr size_t kMaxErrorTextBytes = 512;

/// A protocol error the session raises itself (authentication, roles, framing), whose code a
/// Status does not name. Each string is passed through Printable (bounded, escaped).
v1::Error ProtocolError(v1::ErrorCode code, std::string field, std::string value,
                        std::string allowed_range, std::string message, uint64_t client_seq = 0);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_WIRE_ERROR_H_
