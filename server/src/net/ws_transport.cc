/// @brief WsTransport: one sculpt.v1 message per WebSocket binary message.
#include "net/ws_transport.h"

#include <boost/beast/websocket/ssl.hpp>

#include "sculpt/codec/frame.h"

namespace sculpt::server {

template <class NextLayer>
struct BasicWsTransport<NextLayer>::WriteOp {
  std::vector<Frame> frames;
  size_t next = 0;
  uint64_t bytes = 0;
  WriteHandler done;
};

template <class NextLayer>
BasicWsTransport<NextLayer>::BasicWsTransport(std::unique_ptr<Stream> ws, std::string remote,
                                              uint32_t max_message_bytes,
                                              std::shared_ptr<void> hold)
    : ws_(std::move(ws)),
      remote_(std::move(remote)),
      max_message_bytes_(max_message_bytes),
      hold_(std::move(hold)) {
  ws_->binary(true);
  ws_->auto_fragment(false);
  ws_->read_message_max(max_message_bytes_);
}

template <class NextLayer>
void BasicWsTransport<NextLayer>::AsyncRead(ReadHandler done) {
  ws_->async_read(buffer_, [self = this->shared_from_this(), done = std::move(done)](
                               beast::error_code ec, size_t n) {
    ReadResult r;
    r.bytes = n;
    if (ec == websocket::error::message_too_big) {
      r.end = ReadResult::End::kTooLarge;
      r.reason = ResourceExhausted("WebSocket message length outside [0, " +
                                   std::to_string(self->max_message_bytes_) + "] bytes");
    } else if (ec) {
      r.end = ReadResult::End::kClosed;
      r.reason = Status(Status::Code::kUnavailable,
                        ec == websocket::error::closed ? "client closed" : "read: " + ec.message());
    } else if (self->ws_->got_text()) {
      r.end = ReadResult::End::kMalformed;
      r.reason = InvalidArgument("a text message of " + std::to_string(n) + " bytes");
    } else {
      r.payloads.push_back(beast::buffers_to_string(self->buffer_.data()));
    }
    self->buffer_.consume(self->buffer_.size());
    done(std::move(r));
  });
}

template <class NextLayer>
void BasicWsTransport<NextLayer>::AsyncWrite(std::vector<Frame> frames, WriteHandler done) {
  auto op = std::make_shared<WriteOp>();
  op->frames = std::move(frames);
  op->done = std::move(done);
  writing_ = true;
  WriteNext(std::move(op));
}

template <class NextLayer>
void BasicWsTransport<NextLayer>::WriteNext(std::shared_ptr<WriteOp> op) {
  if (op->next == op->frames.size()) {
    writing_ = false;
    return op->done(Status::Ok(), op->bytes);
  }
  const Frame& f = op->frames[op->next++];
  // The message is the frame without its length prefix: the WebSocket frames it.
  const size_t skip = std::min(f->size(), codec::kFrameHeaderBytes);
  ws_->async_write(asio::buffer(f->data() + skip, f->size() - skip),
                   [self = this->shared_from_this(), op](beast::error_code ec, size_t n) mutable {
                     op->bytes += n;
                     if (ec) {
                       self->writing_ = false;
                       return op->done(
                           Status(Status::Code::kUnavailable, "write: " + ec.message()), op->bytes);
                     }
                     self->WriteNext(std::move(op));
                   });
}

template <class NextLayer>
void BasicWsTransport<NextLayer>::Close() {
  if (closed_) return;
  closed_ = true;
  if (writing_ || !ws_->is_open()) {
    // A peer that does not read would hold a close handshake up: cut the connection.
    beast::error_code ec;
    beast::get_lowest_layer(*ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(*ws_).close();
    return;
  }
  // The close handshake; its own timeout (the stream's handshake timeout) bounds it.
  ws_->async_close(websocket::close_code::normal,
                   [self = this->shared_from_this()](beast::error_code) {});
}

template class BasicWsTransport<beast::tcp_stream>;
template class BasicWsTransport<beast::ssl_stream<beast::tcp_stream>>;

}  // namespace sculpt::server
