/// @brief Printable: untrusted text (a client's names, reasons, object names) made safe for a
/// log line or an error message: bounded in length, control characters and invalid UTF-8 escaped.
#ifndef SCULPT_SERVER_NET_UNTRUSTED_TEXT_H_
#define SCULPT_SERVER_NET_UNTRUSTED_TEXT_H_

#include <cstddef>
#include <string>
#include <string_view>

namespace sculpt::server {

/// How much of one untrusted string a log line or an error quotes by default.
inline constexpr size_t kMaxPrintableBytes = 64;

/// `text` with every control character (U+0000..U+001F, U+007F), backslash and byte of invalid
/// UTF-8 written as \xNN, so it can neither break a log line nor forge one; valid UTF-8 is kept.
/// Text longer than `max_bytes` (of input) is cut at a character boundary and ends with
/// "...(N bytes)" giving the full length. Never fails; the result is valid UTF-8 of at most
/// 4 * max_bytes + 24 bytes.
std::string Printable(std::string_view text, size_t max_bytes = kMaxPrintableBytes);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_UNTRUSTED_TEXT_H_
