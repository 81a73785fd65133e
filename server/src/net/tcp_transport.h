/// @brief TcpTransport: sculpt.v1 messages as length-prefixed frames on a TCP socket (the
/// native clients' transport).
#ifndef SCULPT_SERVER_NET_TCP_TRANSPORT_H_
#define SCULPT_SERVER_NET_TCP_TRANSPORT_H_

#include <array>
#include <string>
#include <vector>

#include "net/net.h"
#include "net/transport.h"
#include "sculpt/codec/frame.h"

namespace sculpt::server {

/// A TCP connection carrying 4-byte length-prefixed frames. Frames are written with
/// scatter/gather straight from the shared buffers. Thread safety: see Transport.
class TcpTransport final : public Transport {
 public:
  /// `socket` must run on the session's strand. A declared frame length above
  /// `max_frame_bytes` ends the read with kTooLarge before anything is allocated for it.
  TcpTransport(tcp::socket socket, uint32_t max_frame_bytes);

  TransportKind kind() const override { return TransportKind::kTcp; }
  std::string remote() const override { return remote_; }
  void AsyncRead(ReadHandler done) override;
  void AsyncWrite(std::vector<Frame> frames, WriteHandler done) override;
  void Close() override;

 private:
  tcp::socket socket_;
  codec::FrameReader reader_;
  std::array<char, 64 * 1024> buf_{};
  std::string remote_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_TCP_TRANSPORT_H_
