/// @brief WsTransport: sculpt.v1 messages as WebSocket binary messages, one per message (the
/// browser client's transport, upgraded from the HTTP port's /ws), in clear or over TLS (WSS).
#ifndef SCULPT_SERVER_NET_WS_TRANSPORT_H_
#define SCULPT_SERVER_NET_WS_TRANSPORT_H_

#include <memory>
#include <string>
#include <vector>

#include "net/beast.h"
#include "net/tls.h"
#include "net/transport.h"

#include <boost/beast/ssl.hpp>

namespace sculpt::server {

/// A WebSocket whose handshake is done. Each ClientMessage arrives as one binary message and
/// each frame leaves as one binary message (the bytes after the length prefix). A text message
/// ends the read with kMalformed; one above `max_message_bytes` with kTooLarge (Beast closes
/// with code 1009). `NextLayer` is a beast::tcp_stream or a beast::ssl_stream over one.
/// Thread safety: see Transport.
template <class NextLayer>
class BasicWsTransport final : public Transport,
                               public std::enable_shared_from_this<BasicWsTransport<NextLayer>> {
 public:
  using Stream = websocket::stream<NextLayer>;

  /// `ws` runs on the session's strand and has accepted the upgrade. `hold` is kept until the
  /// transport is destroyed (the HTTP server's connection slot).
  BasicWsTransport(std::unique_ptr<Stream> ws, std::string remote, uint32_t max_message_bytes,
                   std::shared_ptr<void> hold);

  TransportKind kind() const override { return TransportKind::kWebSocket; }
  std::string remote() const override { return remote_; }
  void AsyncRead(ReadHandler done) override;
  void AsyncWrite(std::vector<Frame> frames, WriteHandler done) override;
  void Close() override;

 private:
  struct WriteOp;
  void WriteNext(std::shared_ptr<WriteOp> op);

  std::unique_ptr<Stream> ws_;
  std::string remote_;
  uint32_t max_message_bytes_;
  std::shared_ptr<void> hold_;
  beast::flat_buffer buffer_;
  bool writing_ = false;
  bool closed_ = false;
};

using WsTransport = BasicWsTransport<beast::tcp_stream>;
using WssTransport = BasicWsTransport<beast::ssl_stream<beast::tcp_stream>>;

extern template class BasicWsTransport<beast::tcp_stream>;
extern template class BasicWsTransport<beast::ssl_stream<beast::tcp_stream>>;

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_WS_TRANSPORT_H_
