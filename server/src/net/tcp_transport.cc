/// @brief TcpTransport: length-prefixed frames on a TCP socket.
#include "net/tcp_transport.h"

#include <spdlog/spdlog.h>

namespace sculpt::server {

TcpTransport::TcpTransport(tcp::socket socket, uint32_t max_frame_bytes)
    : socket_(std::move(socket)), reader_(max_frame_bytes) {
  boost::system::error_code ec;
  const auto ep = socket_.remote_endpoint(ec);
  remote_ = ec ? "?" : ep.address().to_string() + ":" + std::to_string(ep.port());
}

void TcpTransport::AsyncRead(ReadHandler done) {
  socket_.async_read_some(
      asio::buffer(buf_), [this, done = std::move(done)](boost::system::error_code ec, size_t n) {
        ReadResult r;
        r.bytes = n;
        if (!ec) reader_.Feed(buf_.data(), n);
        // Every complete frame goes up, also those that arrived just before an error.
        for (;;) {
          auto next = reader_.Next();
          if (!next.ok()) {
            r.end = ReadResult::End::kTooLarge;
            r.reason = next.status();
            return done(std::move(r));
          }
          if (!next->has_value()) break;
          r.payloads.push_back(std::move(**next));
        }
        if (ec) {
          if (reader_.buffered() > 0 && ec == asio::error::eof) {
            spdlog::info("{}: closed mid-frame ({} bytes of a truncated frame dropped)", remote_,
                         reader_.buffered());
          }
          r.end = ReadResult::End::kClosed;
          r.reason = Status(Status::Code::kUnavailable,
                            ec == asio::error::eof ? "client closed" : "read: " + ec.message());
        }
        done(std::move(r));
      });
}

void TcpTransport::AsyncWrite(std::vector<Frame> frames, WriteHandler done) {
  std::vector<asio::const_buffer> buffers;
  buffers.reserve(frames.size());
  for (const Frame& f : frames) buffers.emplace_back(f->data(), f->size());
  // The frames stay alive in the handler until the write completes.
  asio::async_write(socket_, buffers,
                    [frames = std::move(frames), done = std::move(done)](
                        boost::system::error_code ec, size_t n) {
                      done(ec ? Status(Status::Code::kUnavailable, "write: " + ec.message())
                              : Status::Ok(),
                           n);
                    });
}

void TcpTransport::Close() {
  boost::system::error_code ec;
  socket_.shutdown(tcp::socket::shutdown_both, ec);
  socket_.close(ec);
}

}  // namespace sculpt::server
