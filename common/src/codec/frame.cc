/// @brief Length-prefixed frames: the 4-byte little-endian header writer and the reader.
#include "sculpt/codec/frame.h"

#include <string>
#include <utility>

namespace sculpt::codec {
namespace {

// Below this many consumed bytes the reader never compacts: moving a few bytes each Feed would
// cost more than the memory it returns.
constexpr size_t kMinCompactBytes = 4096;

uint32_t ReadLittleEndian32(const char* p) {
  // Through unsigned char: a plain char is signed here and would sign-extend bytes >= 0x80.
  const auto* u = reinterpret_cast<const unsigned char*>(p);
  return static_cast<uint32_t>(u[0]) | (static_cast<uint32_t>(u[1]) << 8) |
         (static_cast<uint32_t>(u[2]) << 16) | (static_cast<uint32_t>(u[3]) << 24);
}

}  // namespace

void AppendFrame(std::string_view payload, std::string* out) {
  // A payload of 4 GiB or more cannot be described by the header; protobuf refuses to serialize
  // messages above 2 GiB and every sender keeps payloads under max_frame_bytes, so the cast
  // cannot wrap for a frame the peer would accept anyway.
  const uint32_t n = static_cast<uint32_t>(payload.size());
  char header[kFrameHeaderBytes];
  for (size_t i = 0; i < kFrameHeaderBytes; ++i) {
    header[i] = static_cast<char>((n >> (8 * i)) & 0xff);
  }
  out->reserve(out->size() + kFrameHeaderBytes + payload.size());
  out->append(header, kFrameHeaderBytes);
  out->append(payload.data(), payload.size());
}

void FrameReader::Feed(const char* data, size_t n) {
  if (n == 0) return;
  if (offset_ == buffer_.size()) {
    buffer_.clear();
    offset_ = 0;
  } else if (offset_ >= kMinCompactBytes && offset_ >= buffer_.size() / 2) {
    // Compacting only when the consumed prefix is at least half the buffer moves fewer bytes
    // than were consumed since the last compaction: amortised O(1) per byte received.
    buffer_.erase(0, offset_);
    offset_ = 0;
  }
  // Only the bytes that actually arrived are stored; a declared length is never reserved, so
  // a peer cannot make the reader allocate memory it has not sent.
  buffer_.append(data, n);
}

StatusOr<std::optional<std::string>> FrameReader::Next() {
  const size_t available = buffered();
  if (available < kFrameHeaderBytes) return std::optional<std::string>();
  const uint32_t length = ReadLittleEndian32(buffer_.data() + offset_);
  if (length > max_frame_bytes_) {
    // The header stays unconsumed, so every later call reports the same error: the stream
    // cannot be resynchronised and the caller must answer and close.
    return Outside("frame length", std::to_string(length),
                   std::string("[0, ") + std::to_string(max_frame_bytes_) + "]",
                   Status::Code::kResourceExhausted);
  }
  if (available - kFrameHeaderBytes < length) return std::optional<std::string>();
  std::string payload(buffer_, offset_ + kFrameHeaderBytes, length);
  offset_ += kFrameHeaderBytes + length;
  if (offset_ == buffer_.size()) {
    buffer_.clear();
    offset_ = 0;
  }
  return std::optional<std::string>(std::move(payload));
}

}  // namespace sculpt::codec
