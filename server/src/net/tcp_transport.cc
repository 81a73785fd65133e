/// @brief TcpTransport: length-prefixed frames on a TCP socket, in clear or over TLS.
#include "net/tcp_transport.h"

#include <spdlog/spdlog.h>

#include <type_traits>

namespace sculpt::server {
namespace {

bool IsEnd(const boost::system::error_code& ec) {
  // A TLS peer that closes without close_notify ends the stream as an EOF would: the framing
  // (and the Bye) already tells a complete session from a cut one.
  return ec == asio::error::eof || ec == ssl::error::stream_truncated;
}

}  // namespace

template <class Stream>
BasicTcpTransport<Stream>::BasicTcpTransport(Stream stream, uint32_t max_frame_bytes)
    : stream_(std::move(stream)), reader_(max_frame_bytes) {
  boost::system::error_code ec;
  const auto ep = socket().remote_endpoint(ec);
  remote_ = ec ? "?" : ep.address().to_string() + ":" + std::to_string(ep.port());
}

template <class Stream>
void BasicTcpTransport<Stream>::AsyncHandshake(std::chrono::milliseconds timeout,
                                               std::function<void(Status)> done) {
  if constexpr (std::is_same_v<Stream, tcp::socket>) {
    done(Status::Ok());
  } else {
    // The timer lives on the socket's strand; whichever of it and the handshake ends first
    // settles the other (closing the socket aborts the handshake).
    auto timer = std::make_shared<asio::steady_timer>(stream_.get_executor());
    auto timed_out = std::make_shared<bool>(false);
    timer->expires_after(timeout);
    timer->async_wait([self = this->shared_from_this(), timed_out](boost::system::error_code ec) {
      if (ec) return;
      *timed_out = true;
      self->Close();
    });
    stream_.async_handshake(
        ssl::stream_base::server,
        [self = this->shared_from_this(), timer, timed_out, timeout,
         done = std::move(done)](boost::system::error_code ec) {
          timer->cancel();
          if (*timed_out) {
            return done(Status(Status::Code::kUnavailable,
                               "TLS handshake not complete within " +
                                   std::to_string(timeout.count()) + " ms"));
          }
          if (ec) {
            self->Close();
            return done(Status(Status::Code::kUnavailable,
                               "TLS handshake: " + DescribeHandshakeError(ec)));
          }
          done(Status::Ok());
        });
  }
}

template <class Stream>
void BasicTcpTransport<Stream>::AsyncRead(ReadHandler done) {
  stream_.async_read_some(
      asio::buffer(buf_), [self = this->shared_from_this(), done = std::move(done)](
                              boost::system::error_code ec, size_t n) {
        ReadResult r;
        r.bytes = n;
        if (!ec) self->reader_.Feed(self->buf_.data(), n);
        // Every complete frame goes up, also those that arrived just before an error.
        for (;;) {
          auto next = self->reader_.Next();
          if (!next.ok()) {
            r.end = ReadResult::End::kTooLarge;
            r.reason = next.status();
            return done(std::move(r));
          }
          if (!next->has_value()) break;
          r.payloads.push_back(std::move(**next));
        }
        r.partial = self->reader_.buffered() > 0;
        if (ec) {
          if (self->reader_.buffered() > 0 && IsEnd(ec)) {
            spdlog::info("{}: closed mid-frame ({} bytes of a truncated frame dropped)",
                         self->remote_, self->reader_.buffered());
          }
          r.end = ReadResult::End::kClosed;
          r.reason = Status(Status::Code::kUnavailable,
                            IsEnd(ec) ? "client closed" : "read: " + ec.message());
        }
        done(std::move(r));
      });
}

template <class Stream>
void BasicTcpTransport<Stream>::AsyncWrite(std::vector<Frame> frames, WriteHandler done) {
  std::vector<asio::const_buffer> buffers;
  buffers.reserve(frames.size());
  for (const Frame& f : frames) buffers.emplace_back(f->data(), f->size());
  // The frames stay alive in the handler until the write completes. Over TLS, asio::async_write
  // gathers the buffers into records of up to 16 KiB each.
  asio::async_write(stream_, buffers,
                    [self = this->shared_from_this(), frames = std::move(frames),
                     done = std::move(done)](boost::system::error_code ec, size_t n) {
                      done(ec ? Status(Status::Code::kUnavailable, "write: " + ec.message())
                              : Status::Ok(),
                           n);
                    });
}

template <class Stream>
void BasicTcpTransport<Stream>::Close() {
  // Over TLS no close_notify is sent: it would need the peer's answer (a read and a write on
  // the stream while the session's own may be in flight); the session's Bye ends it cleanly.
  boost::system::error_code ec;
  socket().shutdown(tcp::socket::shutdown_both, ec);
  socket().close(ec);
}

template class BasicTcpTransport<tcp::socket>;
template class BasicTcpTransport<ssl::stream<tcp::socket>>;

}  // namespace sculpt::server
