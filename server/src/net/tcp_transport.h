/// @brief TcpTransport: sculpt.v1 messages as length-prefixed frames on a TCP socket (the
/// native clients' transport), in clear or over TLS (TlsTcpTransport).
#ifndef SCULPT_SERVER_NET_TCP_TRANSPORT_H_
#define SCULPT_SERVER_NET_TCP_TRANSPORT_H_

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "net/net.h"
#include "net/tls.h"
#include "net/transport.h"
#include "sculpt/codec/frame.h"

namespace sculpt::server {

/// A TCP connection carrying 4-byte length-prefixed frames; `Stream` is a tcp::socket or an
/// ssl::stream over one. Frames are written with scatter/gather straight from the shared buffers.
/// Thread safety: see Transport.
template <class Stream>
class BasicTcpTransport final : public Transport,
                                public std::enable_shared_from_this<BasicTcpTransport<Stream>> {
 public:
  /// `stream` must run on the session's strand. A declared frame length above
  /// `max_frame_bytes` ends the read with kTooLarge before anything is allocated for it.
  BasicTcpTransport(Stream stream, uint32_t max_frame_bytes);

  /// TLS only: the server side of the handshake, bounded by `timeout` (the socket is closed when
  /// it passes). `done` gets Ok, or Unavailable naming the failure ("timeout", the TLS alert).
  void AsyncHandshake(std::chrono::milliseconds timeout, std::function<void(Status)> done);

  TransportKind kind() const override { return TransportKind::kTcp; }
  std::string remote() const override { return remote_; }
  void AsyncRead(ReadHandler done) override;
  void AsyncWrite(std::vector<Frame> frames, WriteHandler done) override;
  void Close() override;

 private:
  tcp::socket::lowest_layer_type& socket() { return stream_.lowest_layer(); }

  Stream stream_;
  codec::FrameReader reader_;
  std::array<char, 64 * 1024> buf_{};
  std::string remote_;
};

using TcpTransport = BasicTcpTransport<tcp::socket>;
using TlsTcpTransport = BasicTcpTransport<ssl::stream<tcp::socket>>;

extern template class BasicTcpTransport<tcp::socket>;
extern template class BasicTcpTransport<ssl::stream<tcp::socket>>;

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_TCP_TRANSPORT_H_
