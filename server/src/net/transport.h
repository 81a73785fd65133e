/// @brief Transport: how one client's messages arrive and leave (length-prefixed TCP frames or
/// WebSocket binary messages), behind one interface so a Session does not know which.
#ifndef SCULPT_SERVER_NET_TRANSPORT_H_
#define SCULPT_SERVER_NET_TRANSPORT_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sculpt/core/status.h"

namespace sculpt::server {

/// One serialized sculpt.v1.ServerMessage with its 4-byte length prefix (codec/frame.h), built
/// once and shared, immutable, by every session it goes to. A transport that frames messages
/// itself (WebSocket) writes the bytes after the prefix.
using Frame = std::shared_ptr<const std::string>;

/// The kinds of transport, as metrics label them.
enum class TransportKind { kTcp = 0, kWebSocket = 1 };
inline constexpr int kTransportKinds = 2;
/// "tcp" or "ws".
const char* TransportName(TransportKind kind);

/// What one read brought: the complete messages received (in order), and whether the stream
/// ended after them and how.
struct ReadResult {
  enum class End {
    kNone,       // more may follow: read again
    kClosed,     // the peer closed or the connection failed; `reason` says which
    kTooLarge,   // a message above the maximum: `reason` is the ResourceExhausted naming it
    kMalformed,  // framing the protocol does not allow (a WebSocket text message)
  };
  std::vector<std::string> payloads;  // each one serialized sculpt.v1.ClientMessage
  End end = End::kNone;
  Status reason;
  uint64_t bytes = 0;  // bytes taken off the connection by this read
  bool partial = false;  // the start of a message is buffered, its end not yet received
};

/// A client connection as a session sees it. Every method is called on the session's strand
/// and every handler runs there; one read and one write may be in flight at a time.
/// Thread safety: none beyond that strand.
class Transport {
 public:
  using ReadHandler = std::function<void(ReadResult)>;
  /// ok, or Unavailable naming the write error; `bytes` written either way.
  using WriteHandler = std::function<void(Status, uint64_t bytes)>;

  virtual ~Transport() = default;

  virtual TransportKind kind() const = 0;
  /// The peer's address, for logs ("127.0.0.1:5555").
  virtual std::string remote() const = 0;
  /// Reads until at least one message is complete or the stream ends.
  virtual void AsyncRead(ReadHandler done) = 0;
  /// Writes every frame, in order, then calls `done`.
  virtual void AsyncWrite(std::vector<Frame> frames, WriteHandler done) = 0;
  /// Ends the connection: gracefully when nothing is being written (a WebSocket close
  /// handshake), at once otherwise. Pending operations complete with errors. Idempotent.
  virtual void Close() = 0;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_TRANSPORT_H_
