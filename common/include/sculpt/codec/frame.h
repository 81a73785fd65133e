/// @brief Length-prefixed frames: a 4-byte little-endian payload length, then the payload (one
/// serialized sculpt.v1 message). Used on TCP by the server, the client library and the tests.
#ifndef SCULPT_CODEC_FRAME_H_
#define SCULPT_CODEC_FRAME_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "sculpt/core/status.h"

namespace sculpt::codec {

inline constexpr size_t kFrameHeaderBytes = 4;
/// Default largest payload accepted (1 MiB); scenes may lower it.
inline constexpr uint32_t kDefaultMaxFrameBytes = 1u << 20;

/// Appends header + payload to `out`.
void AppendFrame(std::string_view payload, std::string* out);

/// Serializes a protobuf message and appends it as one frame. Returns false if serialization
/// fails (it does not for well-formed messages).
template <typename Message>
bool AppendMessage(const Message& message, std::string* out) {
  const size_t start = out->size();
  out->resize(start + kFrameHeaderBytes);
  if (!message.AppendToString(out)) {
    out->resize(start);
    return false;
  }
  const uint32_t n = static_cast<uint32_t>(out->size() - start - kFrameHeaderBytes);
  for (size_t i = 0; i < kFrameHeaderBytes; ++i) {
    (*out)[start + i] = static_cast<char>((n >> (8 * i)) & 0xff);
  }
  return true;
}

/// Incremental frame splitter for a byte stream: feed what the socket delivered, take complete
/// frames out. Untrusted input: a declared length above the maximum is an error (the caller
/// answers and closes), never an allocation of that size.
/// Thread safety: none; one reader per connection.
class FrameReader {
 public:
  explicit FrameReader(uint32_t max_frame_bytes = kDefaultMaxFrameBytes)
      : max_frame_bytes_(max_frame_bytes) {}

  /// Appends received bytes.
  void Feed(const char* data, size_t n);
  /// The next complete payload; std::nullopt when more bytes are needed; ResourceExhausted
  /// ("frame length=N outside [0, max]") when the header declares more than the maximum.
  StatusOr<std::optional<std::string>> Next();
  /// Bytes received but not yet returned (a partial frame at a clean close means truncation).
  size_t buffered() const { return buffer_.size() - offset_; }
  uint32_t max_frame_bytes() const { return max_frame_bytes_; }

 private:
  uint32_t max_frame_bytes_;
  std::string buffer_;
  size_t offset_ = 0;
};

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_FRAME_H_
