/// @brief Client: the connection state machine, batched writes, the pending-stroke table that
/// makes resends safe, and event delivery.
#include "sculpt/client/client.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509v3.h>

#include "lib/net.h"
#include "sculpt/codec/frame.h"

namespace sculpt::client {

using Clock = std::chrono::steady_clock;

// Answers to undo requests kept for WaitUndoAck; beyond it the oldest go (a caller that only
// reads events never waits for them).
constexpr size_t kMaxUndoAnswers = 1024;
// Resends written at once after a Join; the rest are paced (Impl::PaceResendsLocked). Under the
// server's default stroke burst of 60 per connection, and 4 clients' worth under the budget
// shared by one address.
constexpr size_t kResendBurst = 24;
// Seconds of Welcome.max_strokes_per_second a JoinScene declares as resends at most: the server
// lets limits.stroke_burst + 5 s of strokes pass free (proto/README.md, "Declared resends").
constexpr double kDeclaredResendSeconds = 5.0;

struct IoThread::Impl {
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work{io.get_executor()};
  std::thread thread;
};

IoThread::IoThread() : impl_(std::make_unique<Impl>()) {
  Impl* impl = impl_.get();
  impl_->thread = std::thread([impl] { impl->io.run(); });
}

IoThread::~IoThread() {
  impl_->work.reset();
  // Clients close their sockets before letting go of the thread; whatever is still queued (a
  // handler of a client being torn down) is destroyed with the io_context.
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

namespace {

/// One TCP connection, in clear or over TLS (`tls` wraps `socket`). The socket, `tls`,
/// `reader`, `buf` and `writing` are touched only on the I/O thread; the rest is guarded by
/// Client::Impl::mu.
struct Conn {
  Conn(asio::io_context& io, uint32_t max_frame_bytes) : socket(io), reader(max_frame_bytes) {}

  template <class Handler>
  void AsyncReadSome(asio::mutable_buffer b, Handler&& h) {
    if (tls) return tls->async_read_some(b, std::forward<Handler>(h));
    socket.async_read_some(b, std::forward<Handler>(h));
  }
  template <class Handler>
  void AsyncWrite(asio::const_buffer b, Handler&& h) {
    if (tls) return asio::async_write(*tls, b, std::forward<Handler>(h));
    asio::async_write(socket, b, std::forward<Handler>(h));
  }

  tcp::socket socket;
  std::unique_ptr<ssl::stream<tcp::socket&>> tls;
  codec::FrameReader reader;
  std::array<char, 64 * 1024> buf{};
  std::string writing;

  std::string out;                 // frames waiting for the next write
  std::vector<uint64_t> out_seqs;  // strokes among them (their send time is the write's)
  bool writing_active = false;
  bool write_posted = false;
  bool shutdown_after_write = false;
  bool shut_down = false;
  bool closed = false;
};

std::string Ms(std::chrono::milliseconds ms) { return std::to_string(ms.count()) + " ms"; }

std::string TakeOpenSslError() {
  unsigned long last = 0;
  while (unsigned long e = ERR_get_error()) last = e;
  const char* reason = last ? ERR_reason_error_string(last) : nullptr;
  return reason ? reason : "unreadable";
}

// TLS 1.2+ with forward-secret AEAD suites only, as sculptd offers.
StatusOr<std::shared_ptr<ssl::context>> MakeClientTlsContext(const ClientTlsOptions& o) {
  ERR_clear_error();
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_client);
  SSL_CTX* native = ctx->native_handle();
  SSL_CTX_set_min_proto_version(native, TLS1_2_VERSION);
  SSL_CTX_set_options(native, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
  SSL_CTX_set_cipher_list(native,
                          "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:"
                          "ECDHE-ECDSA-AES256-GCM-SHA384:ECDHE-RSA-AES256-GCM-SHA384:"
                          "ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305");
  boost::system::error_code ec;
  if (o.ca_file.empty()) {
    ctx->set_default_verify_paths(ec);
  } else if (SSL_CTX_load_verify_locations(native, o.ca_file.c_str(), nullptr) != 1) {
    return InvalidArgument("tls.ca_file=" + o.ca_file + ": not a readable PEM CA file (" +
                           TakeOpenSslError() + ")");
  }
  if (o.cert_file.empty() != o.key_file.empty()) {
    return InvalidArgument("a client certificate needs both tls.cert_file and tls.key_file");
  }
  if (!o.cert_file.empty()) {
    if (SSL_CTX_use_certificate_chain_file(native, o.cert_file.c_str()) != 1) {
      return InvalidArgument("tls.cert_file=" + o.cert_file + ": not a readable PEM certificate (" +
                             TakeOpenSslError() + ")");
    }
    if (SSL_CTX_use_PrivateKey_file(native, o.key_file.c_str(), SSL_FILETYPE_PEM) != 1 ||
        SSL_CTX_check_private_key(native) != 1) {
      return InvalidArgument("tls.key_file=" + o.key_file + ": not the PEM key of tls.cert_file=" +
                             o.cert_file + " (" + TakeOpenSslError() + ")");
    }
  }
  ctx->set_verify_mode(ssl::verify_peer);
  return ctx;
}

// Why a handshake failed, with the certificate check's own reason when that was it.
std::string HandshakeFailure(const boost::system::error_code& ec, SSL* ssl) {
  std::string text = ec.message();
  const long verify = ssl ? SSL_get_verify_result(ssl) : X509_V_OK;
  if (verify != X509_V_OK) {
    text += std::string(": ") + X509_verify_cert_error_string(verify);
  } else if (ec == asio::error::eof || ec == ssl::error::stream_truncated) {
    text += " (is the server's port TLS?)";
  }
  return text;
}

}  // namespace

struct Client::Impl : std::enable_shared_from_this<Client::Impl> {
  enum class Phase {
    kIdle,
    kConnected,
    kAwaitWelcome,
    kAuthed,
    kAwaitJoin,
    kJoinComplete,  // every chunk arrived; Join() resends before strokes flow
    kJoined,
    kClosing,
    kDisconnected,
  };

  struct Pending {
    std::string frame;
    Clock::time_point sent_at;
    bool written = false;
    bool undo = false;  // an UndoRequest (answered by UndoAck), else a stroke (Ack)
    bool redo = false;
  };

  Impl(asio::io_context& io_context, ClientOptions opts)
      : io(io_context), options(std::move(opts)), next_seq(std::max<uint64_t>(1, options.first_client_seq)) {}

  // --- I/O thread ------------------------------------------------------------------------

  void StartRead(const std::shared_ptr<Conn>& c) {
    auto self = shared_from_this();
    c->AsyncReadSome(
        asio::buffer(c->buf), [self, c](boost::system::error_code ec, size_t n) {
          if (ec) {
            // A TLS server that closes without close_notify ends the stream as EOF does.
            self->Lost(c, ec == asio::error::eof || ec == ssl::error::stream_truncated
                              ? "server closed the connection"
                              : "read: " + ec.message());
            return;
          }
          c->reader.Feed(c->buf.data(), n);
          // Parsed outside the lock: a state chunk is 256 KiB, and SendStroke waits on mu.
          std::vector<v1::ServerMessage> messages;
          std::string failure;
          for (;;) {
            auto next = c->reader.Next();
            if (!next.ok()) {
              failure = "server frame: " + next.status().message();
              break;
            }
            if (!next->has_value()) break;
            messages.emplace_back();
            if (!messages.back().ParseFromString(**next)) {
              messages.pop_back();
              failure = "a server frame does not parse as sculpt.v1.ServerMessage";
              break;
            }
          }
          {
            std::lock_guard<std::mutex> lock(self->mu);
            self->stats.bytes_received += n;
            if (c == self->conn && !c->closed) {
              for (v1::ServerMessage& m : messages) self->OnMessageLocked(m);
            }
          }
          if (!failure.empty()) {
            self->Lost(c, failure);
            return;
          }
          self->StartRead(c);
        });
  }

  void OnMessageLocked(v1::ServerMessage& m) {
    switch (m.body_case()) {
      case v1::ServerMessage::kWelcome:
        if (phase == Phase::kAwaitWelcome) {
          welcome = m.welcome();
          phase = Phase::kAuthed;
          cv.notify_all();
        }
        return;
      case v1::ServerMessage::kSceneInfo:
        if (phase == Phase::kAwaitJoin) {
          join = JoinedScene{};
          join.info = m.scene_info();
          next_chunk.clear();
          objects_complete = 0;
          for (const v1::ObjectInfo& o : join.info.objects()) next_chunk[o.name()] = 0;
          if (join.info.objects_size() == 0 || options.skip_state) CompleteJoinLocked();
        }
        return;
      case v1::ServerMessage::kStateChunk:
        return OnChunkLocked(*m.mutable_state_chunk());
      case v1::ServerMessage::kAck:
        return OnAckLocked(m.ack());
      case v1::ServerMessage::kUndoAck:
        return OnUndoAckLocked(std::move(*m.mutable_undo_ack()));
      case v1::ServerMessage::kHistory:
        if (history_waiting.erase(m.history().request_id()) > 0) {
          history_answers[m.history().request_id()] = std::move(*m.mutable_history());
          cv.notify_all();
        }
        return;
      case v1::ServerMessage::kPresence: {
        ++stats.presence;
        Event e;
        e.type = Event::Type::kPresence;
        e.presence = std::move(*m.mutable_presence());
        return EmitLocked(std::move(e));
      }
      case v1::ServerMessage::kError:
        return OnErrorLocked(m.error());
      case v1::ServerMessage::kRedirect:
        // Cluster mode: the scene's owner is another member; Join follows it.
        if (phase == Phase::kAwaitJoin) {
          redirect = std::move(*m.mutable_redirect());
          // Closed here, before the server's Bye and close are read, so the kDisconnected event
          // names the owner rather than the end of the stream.
          CloseConnLocked(conn, "redirected to the scene's owner, member " + redirect->member() +
                                    " at " + redirect->tcp_address());
        }
        return;
      case v1::ServerMessage::kBye: {
        Event e;
        e.type = Event::Type::kBye;
        e.reason = m.bye().reason();
        return EmitLocked(std::move(e));
      }
      case v1::ServerMessage::kEdit:
      case v1::ServerMessage::kLeafDelta:
      case v1::ServerMessage::kMeshChunk:
      case v1::ServerMessage::kContour:  // ball skins (SkinClient)
      case v1::ServerMessage::kSkinAck:
      case v1::ServerMessage::kPaintAck:  // paints (issue 7)
      case v1::ServerMessage::kModelAck:  // hyperpatch model intents (issue 7)
      case v1::ServerMessage::kLogRecords:  // cluster mode: to a standby's follower only
        ++stats.replication_messages;
        if (replication_handler) replication_handler(std::move(m));
        return;
      case v1::ServerMessage::BODY_NOT_SET:
        return;
    }
  }

  void OnChunkLocked(v1::StateChunk& chunk) {
    stats.state_bytes_received += chunk.data().size();
    if (phase != Phase::kAwaitJoin) return;
    auto it = next_chunk.find(chunk.object());
    // The server is trusted for content, but a chunk that does not continue its object's
    // sequence would assemble into garbage: fail the join rather than deserialize that.
    if (it == next_chunk.end()) {
      join_failure = DataLoss("StateChunk.object=" + chunk.object() + " outside SceneInfo");
    } else if (chunk.index() != it->second || chunk.count() == 0 ||
               chunk.index() >= chunk.count()) {
      join_failure =
          DataLoss("StateChunk.index=" + std::to_string(chunk.index()) + " outside [" +
                   std::to_string(it->second) + ", " + std::to_string(it->second) + "] of count " +
                   std::to_string(chunk.count()) + " for " + chunk.object());
    } else if (chunk.global_seq() != join.info.global_seq()) {
      join_failure = DataLoss("StateChunk.global_seq=" + std::to_string(chunk.global_seq()) +
                              " outside [" + std::to_string(join.info.global_seq()) + ", " +
                              std::to_string(join.info.global_seq()) + "] (SceneInfo)");
    }
    if (join_failure) {
      cv.notify_all();
      return;
    }
    join.state[chunk.object()].append(chunk.data());
    ++it->second;
    if (it->second == chunk.count() && ++objects_complete == next_chunk.size()) {
      CompleteJoinLocked();
    }
  }

  void CompleteJoinLocked() {
    phase = Phase::kJoinComplete;
    cv.notify_all();
  }

  void OnAckLocked(const v1::Ack& a) {
    Event e;
    e.type = Event::Type::kAck;
    e.ack = a;
    auto it = pending.find(a.client_seq());
    if (it == pending.end() || it->second.undo) {
      // Settled already: the ack of a stroke resent just before its first ack arrived.
      ++stats.stray_acks;
    } else {
      e.latency_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - it->second.sent_at).count();
      pending.erase(it);
      ++stats.acks;
      if (a.duplicate()) {
        ++stats.duplicate_acks;
      } else {
        if (a.global_seq_first() <= last_fresh_global_seq) ++stats.acks_out_of_order;
        last_fresh_global_seq = a.global_seq_first();
        stats.poses_acked += a.edits();
        if (a.edits() > 0) {
          stats.last_global_seq =
              std::max(stats.last_global_seq, a.global_seq_first() + a.edits() - 1);
        }
      }
      if (pending.empty()) cv.notify_all();
    }
    EmitLocked(std::move(e));
  }

  void OnUndoAckLocked(v1::UndoAck&& a) {
    Event e;
    e.type = Event::Type::kUndoAck;
    auto it = pending.find(a.client_seq());
    if (it == pending.end() || !it->second.undo) {
      ++stats.stray_acks;  // the answer to a resend of a request answered already
    } else {
      e.latency_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - it->second.sent_at).count();
      pending.erase(it);
      ++stats.undo_acks;
      if (!a.accepted()) ++stats.undos_refused;
      if (!a.duplicate() && a.global_seq() > 0) {
        stats.last_global_seq = std::max(stats.last_global_seq, a.global_seq());
      }
      AnswerUndoLocked(a);
    }
    e.undo_ack = std::move(a);
    EmitLocked(std::move(e));
  }

  /// Keeps the answer for WaitUndoAck (bounded) and wakes the waiters.
  void AnswerUndoLocked(const v1::UndoAck& a) {
    undo_answers[a.client_seq()] = a;
    while (undo_answers.size() > kMaxUndoAnswers) undo_answers.erase(undo_answers.begin());
    cv.notify_all();
  }

  /// A pending undo refused by an Error rather than an UndoAck: answered as an UndoAck with
  /// accepted false and that error, so callers handle one shape.
  void RefuseUndoLocked(uint64_t seq, const Pending& p, const v1::Error& error) {
    v1::UndoAck a;
    a.set_client_seq(seq);
    a.set_redo(p.redo);
    a.set_accepted(false);
    *a.mutable_error() = error;
    ++stats.undos_refused;
    AnswerUndoLocked(a);
  }

  void OnErrorLocked(const v1::Error& error) {
    ++stats.errors;
    Event e;
    e.type = Event::Type::kError;
    e.error = error;
    // A history request refused before it was read (the rate limit names it in the value) or by
    // a server that does not know it: every waiting one would meet the same answer.
    const auto names_history = [](const std::string& s) {
      return s.rfind("HistoryRequest", 0) == 0;
    };
    if (!history_waiting.empty() &&
        (names_history(error.field()) || names_history(error.value()) ||
         (error.code() == v1::ERROR_CODE_MALFORMED && error.field() == "ClientMessage.body"))) {
      for (uint64_t id : history_waiting) {
        v1::HistoryAnswer a;
        a.set_request_id(id);
        *a.mutable_error() = error;
        history_answers[id] = std::move(a);
      }
      history_waiting.clear();
      cv.notify_all();
    }
    if (error.client_seq() == 0 && error.code() == v1::ERROR_CODE_MALFORMED &&
        error.field() == "ClientMessage.body") {
      // A server older than undo does not know the message: every pending request would meet
      // the same answer, so they are settled (refused) now rather than left to time out.
      for (auto u = pending.begin(); u != pending.end();) {
        if (!u->second.undo) {
          ++u;
          continue;
        }
        e.refused = true;
        RefuseUndoLocked(u->first, u->second, error);
        u = pending.erase(u);
      }
    }
    if (error.code() == v1::ERROR_CODE_UNAVAILABLE && error.client_seq() != 0) {
      // Cluster mode: the member may not acknowledge the scene now (it lost its ownership).
      // Nothing was acknowledged, so the request stays pending and Reconnect() resends it with
      // the same client_seq; the scene's owner recognises one it applied (Ack.duplicate). The
      // connection is closed now: nothing more goes to a member that may not acknowledge, and
      // the resends on the next connection go out in order before any newer request.
      const std::string reason = "the server refused client_seq " +
                                 std::to_string(error.client_seq()) + ": " + error.message();
      EmitLocked(std::move(e));
      if (conn) CloseConnLocked(conn, reason);
      return;
    }
    auto it = error.client_seq() != 0 ? pending.find(error.client_seq()) : pending.end();
    if (it != pending.end()) {
      // Refused strokes (and undos) are not retried with the same client_seq: once a later one
      // of this client is applied, the server would take the old number for a duplicate.
      e.refused = true;
      e.latency_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - it->second.sent_at).count();
      if (it->second.undo) {
        RefuseUndoLocked(it->first, it->second, error);
      } else {
        ++stats.refused;
      }
      pending.erase(it);
      cv.notify_all();
    } else if (phase == Phase::kAwaitWelcome || phase == Phase::kAwaitJoin) {
      handshake_error = error;
      cv.notify_all();
    }
    EmitLocked(std::move(e));
  }

  /// The connection ended (read or write failure, EOF, a bad frame). Idempotent.
  void Lost(const std::shared_ptr<Conn>& c, const std::string& reason) {
    std::lock_guard<std::mutex> lock(mu);
    if (c->closed) return;
    CloseConnLocked(c, reason);
  }

  /// Marks `c` closed and closes its socket on the I/O thread.
  void CloseConnLocked(const std::shared_ptr<Conn>& c, const std::string& reason) {
    if (c->closed) return;
    c->closed = true;
    asio::post(io, [c] {
      boost::system::error_code ignored;
      c->socket.close(ignored);
    });
    if (c == conn) {
      phase = Phase::kDisconnected;
      disconnect_reason = reason;
      Event e;
      e.type = Event::Type::kDisconnected;
      e.reason = reason;
      EmitLocked(std::move(e));
    }
    cv.notify_all();
  }

  void DoWrite(const std::shared_ptr<Conn>& c) {
    std::unique_lock<std::mutex> lock(mu);
    c->write_posted = false;
    if (c->closed || c->writing_active) return;
    if (c->out.empty()) {
      if (c->shutdown_after_write && !c->shut_down) {
        // Half-close: the server reads every frame before the end of stream, and keeps
        // answering until it sees it; the read loop closes the socket at EOF.
        c->shut_down = true;
        boost::system::error_code ignored;
        c->socket.shutdown(tcp::socket::shutdown_send, ignored);
      }
      return;
    }
    c->writing.swap(c->out);
    c->out.clear();
    const auto now = Clock::now();
    for (uint64_t seq : c->out_seqs) {
      auto it = pending.find(seq);
      if (it != pending.end()) it->second.sent_at = now;
    }
    c->out_seqs.clear();
    c->writing_active = true;
    lock.unlock();
    auto self = shared_from_this();
    c->AsyncWrite(asio::buffer(c->writing),
                      [self, c](boost::system::error_code ec, size_t n) {
                        c->writing.clear();
                        {
                          std::lock_guard<std::mutex> lock(self->mu);
                          c->writing_active = false;
                          self->stats.bytes_sent += n;
                        }
                        if (ec) {
                          self->Lost(c, "write: " + ec.message());
                          return;
                        }
                        self->DoWrite(c);
                      });
  }

  void FlushEvents() {
    std::vector<Event> batch;
    {
      std::lock_guard<std::mutex> lock(mu);
      batch.swap(outbox);
      flush_posted = false;
      ++delivering;
    }
    {
      std::lock_guard<std::mutex> handler_lock(handler_mu);
      if (handler) {
        for (const Event& e : batch) handler(e);
        batch.clear();
      }
    }
    std::lock_guard<std::mutex> lock(mu);
    for (Event& e : batch) {
      if (events.size() >= options.max_queued_events) {
        events.pop_front();
        ++stats.events_dropped;
      }
      events.push_back(std::move(e));
    }
    --delivering;
    cv.notify_all();
  }

  /// No event is waiting for or in delivery (WaitAllAcked promises the acks were delivered).
  bool DeliveredLocked() const { return outbox.empty() && delivering == 0; }

  // --- Any thread, with mu held -----------------------------------------------------------

  /// Events are delivered on the I/O thread, in order, outside mu (a handler may call back).
  void EmitLocked(Event e) {
    outbox.push_back(std::move(e));
    if (!flush_posted) {
      flush_posted = true;
      auto self = shared_from_this();
      asio::post(io, [self] { self->FlushEvents(); });
    }
  }

  void KickLocked(const std::shared_ptr<Conn>& c) {
    if (c->writing_active || c->write_posted) return;
    c->write_posted = true;
    auto self = shared_from_this();
    asio::post(io, [self, c] { self->DoWrite(c); });
  }

  void QueueLocked(const std::string& frame, uint64_t seq) {
    if (!conn || conn->closed) return;
    conn->out += frame;
    if (seq != 0) conn->out_seqs.push_back(seq);
    KickLocked(conn);
  }

  /// Writes the pending requests not yet on `c` in client_seq order, at most `burst` now and the
  /// rest one every `interval`, on the I/O thread; stops when `c` is no longer the joined
  /// connection (the next Join starts again).
  void PaceResendsLocked(const std::shared_ptr<Conn>& c, size_t burst,
                         std::chrono::microseconds interval) {
    size_t n = 0;
    for (auto& [seq, p] : pending) {
      if (p.written) continue;
      if (n == burst) {
        auto timer = std::make_shared<asio::steady_timer>(io, interval);
        auto self = shared_from_this();
        timer->async_wait([self, c, timer, interval](boost::system::error_code ec) {
          if (ec) return;
          std::lock_guard<std::mutex> lock(self->mu);
          if (self->conn != c || c->closed || self->phase != Phase::kJoined) return;
          self->PaceResendsLocked(c, 1, interval);
        });
        return;
      }
      p.written = true;
      QueueLocked(p.frame, seq);
      ++n;
    }
    resend_backlog = false;
  }

  template <typename Message>
  static std::string Frame(const Message& m) {
    std::string frame;
    codec::AppendMessage(m, &frame);
    return frame;
  }

  /// Flushes, half-closes and waits for the server's end of stream (bounded), then closes.
  Status EndConnection(std::unique_lock<std::mutex>& lock, const std::string& reason,
                       bool say_bye) {
    std::shared_ptr<Conn> c = conn;
    if (!c || c->closed) return Status::Ok();
    if (say_bye && phase != Phase::kConnected) {
      v1::ClientMessage m;
      m.mutable_bye()->set_reason(reason);
      QueueLocked(Frame(m), 0);
    }
    phase = Phase::kClosing;
    c->shutdown_after_write = true;
    KickLocked(c);
    const auto limit =
        std::min<std::chrono::milliseconds>(options.timeout, std::chrono::seconds(2));
    if (!cv.wait_for(lock, limit, [&] { return c->closed; })) {
      CloseConnLocked(c, reason + " (the server did not close within " + Ms(limit) + ")");
      return Status::Ok();
    }
    return Status::Ok();
  }

  asio::io_context& io;
  const ClientOptions options;

  mutable std::mutex mu;
  std::condition_variable cv;
  Phase phase = Phase::kIdle;
  std::shared_ptr<Conn> conn;
  std::shared_ptr<ssl::context> tls_context;  // built at the first Connect with options.tls
  std::string disconnect_reason;

  std::string host;
  uint16_t port = 0;
  std::string token;
  v1::Role role = v1::ROLE_UNSPECIFIED;
  std::string name;
  uint64_t client_id = 0;
  std::string scene;
  bool joined_once = false;
  // Cluster mode: the members' TCP addresses (HOST:PORT) the last SceneInfo that listed any
  // named, valid and distinct, at most kMaxLearntMembers; Reconnect() tries them after
  // options.cluster_members.
  std::vector<std::string> learnt_members;

  v1::Welcome welcome;
  // Resends after a reconnect go out paced (PaceResendsLocked): true while pending requests
  // wait for the pacer, which also carries the requests made meanwhile, in client_seq order.
  bool resend_backlog = false;
  std::optional<v1::Error> handshake_error;
  JoinedScene join;
  std::map<std::string, uint32_t> next_chunk;
  size_t objects_complete = 0;
  std::optional<Status> join_failure;
  std::optional<v1::Redirect> redirect;  // the answer to the JoinScene in flight, if redirected
  v1::SceneInfo scene_info;

  uint64_t next_seq = 1;
  std::map<uint64_t, Pending> pending;  // strokes and undo requests, by client_seq
  std::map<uint64_t, v1::UndoAck> undo_answers;
  // History view requests sent and not answered, and answers not yet taken, by request_id.
  uint64_t next_history_id = 1;
  std::set<uint64_t> history_waiting;
  std::map<uint64_t, v1::HistoryAnswer> history_answers;
  uint64_t last_fresh_global_seq = 0;

  std::vector<Event> outbox;
  bool flush_posted = false;
  int delivering = 0;
  std::deque<Event> events;
  ClientStats stats;

  std::mutex handler_mu;  // taken before mu, never after
  EventHandler handler;
  std::function<void(v1::ServerMessage&&)> replication_handler;
};

Client::Client(ClientOptions options) {
  io_ = options.io ? options.io : std::make_shared<IoThread>();
  options.io = nullptr;  // the Impl must not keep its own thread alive (see ~IoThread)
  impl_ = std::make_shared<Impl>(io_->impl().io, std::move(options));
}

Client::~Client() {
  SetEventHandler(nullptr);
  (void)Close("client destroyed");
  std::lock_guard<std::mutex> lock(impl_->mu);
  if (impl_->conn) impl_->CloseConnLocked(impl_->conn, "client destroyed");
}

Status Client::Connect(const std::string& host, uint16_t port) {
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (impl_->conn) impl_->CloseConnLocked(impl_->conn, "reconnecting");
  }
  const ClientTlsOptions& tls = impl_->options.tls;
  if (tls.enabled && !impl_->tls_context) {
    auto ctx = MakeClientTlsContext(tls);
    if (!ctx.ok()) return ctx.status();
    impl_->tls_context = std::move(ctx).value();
  }
  auto c = std::make_shared<Conn>(impl_->io, impl_->options.max_frame_bytes);
  if (tls.enabled) {
    c->tls = std::make_unique<ssl::stream<tcp::socket&>>(c->socket, *impl_->tls_context);
    const std::string name = tls.server_name.empty() ? host : tls.server_name;
    SSL* native = c->tls->native_handle();
    boost::system::error_code not_ip;
    asio::ip::make_address(name, not_ip);
    if (not_ip) SSL_set_tlsext_host_name(native, name.c_str());  // SNI takes names only
    if (tls.verify_server_name) {
      X509_VERIFY_PARAM* param = SSL_get0_param(native);
      if (!not_ip) {
        X509_VERIFY_PARAM_set1_ip_asc(param, name.c_str());
      } else {
        X509_VERIFY_PARAM_set_hostflags(param, X509_CHECK_FLAG_NO_PARTIAL_WILDCARDS);
        X509_VERIFY_PARAM_set1_host(param, name.c_str(), 0);
      }
    }
  }
  // What failed: the connection, or (`handshake`) the TLS handshake after it.
  struct Outcome {
    boost::system::error_code ec;
    bool handshake = false;
    std::string detail;
  };
  auto resolver = std::make_shared<tcp::resolver>(impl_->io);
  auto done = std::make_shared<std::promise<Outcome>>();
  auto result = done->get_future();
  asio::post(impl_->io, [c, resolver, done, host, port] {
    resolver->async_resolve(
        host, std::to_string(port),
        [c, resolver, done](boost::system::error_code ec, tcp::resolver::results_type results) {
          if (ec) {
            done->set_value(Outcome{ec, false, {}});
            return;
          }
          asio::async_connect(c->socket, results,
                              [c, done](boost::system::error_code ec, const tcp::endpoint&) {
                                if (ec || !c->tls) {
                                  if (!ec) {
                                    boost::system::error_code ignored;
                                    c->socket.set_option(tcp::no_delay(true), ignored);
                                  }
                                  done->set_value(Outcome{ec, false, {}});
                                  return;
                                }
                                boost::system::error_code ignored;
                                c->socket.set_option(tcp::no_delay(true), ignored);
                                c->tls->async_handshake(
                                    ssl::stream_base::client,
                                    [c, done](boost::system::error_code ec) {
                                      done->set_value(
                                          {ec, true,
                                           ec ? HandshakeFailure(ec, c->tls->native_handle())
                                              : ""});
                                    });
                              });
        });
  });
  const std::string where = host + ":" + std::to_string(port);
  if (result.wait_for(impl_->options.timeout) != std::future_status::ready) {
    asio::post(impl_->io, [c, resolver] {
      resolver->cancel();
      boost::system::error_code ignored;
      c->socket.close(ignored);
    });
    return Status(Status::Code::kUnavailable,
                  "connect to " + where + ": no answer within " + Ms(impl_->options.timeout));
  }
  const Outcome outcome = result.get();
  if (outcome.ec) {
    if (outcome.handshake) {
      asio::post(impl_->io, [c] {
        boost::system::error_code ignored;
        c->socket.close(ignored);
      });
      return Status(Status::Code::kUnavailable,
                    "TLS handshake with " + where + " failed: " + outcome.detail);
    }
    return Status(Status::Code::kUnavailable, "connect to " + where + ": " + outcome.ec.message());
  }
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    impl_->conn = c;
    impl_->phase = Impl::Phase::kConnected;
    impl_->host = host;
    impl_->port = port;
  }
  auto impl = impl_;
  asio::post(impl_->io, [impl, c] { impl->StartRead(c); });
  return Status::Ok();
}

StatusOr<v1::Welcome> Client::Hello(const std::string& token, v1::Role role,
                                    const std::string& name, uint64_t client_id) {
  Impl& d = *impl_;
  std::unique_lock<std::mutex> lock(d.mu);
  if (d.conn && d.conn->closed && d.phase == Impl::Phase::kDisconnected) {
    // Closed between Connect and Hello: a TLS server refusing the client's certificate (or
    // its absence) does so after the client's side of the handshake.
    return Status(Status::Code::kUnavailable,
                  "connection lost before Hello: " + d.disconnect_reason);
  }
  if (!d.conn || d.conn->closed || d.phase != Impl::Phase::kConnected) {
    return FailedPrecondition("Hello needs a new connection: call Connect first");
  }
  if (client_id == 0) client_id = d.client_id != 0 ? d.client_id : NewClientId();
  d.token = token;
  d.role = role;
  d.name = name;
  d.client_id = client_id;
  d.handshake_error.reset();
  v1::ClientMessage m;
  v1::Hello* h = m.mutable_hello();
  h->set_protocol_version(1);
  h->set_token(token);
  h->set_role(role);
  h->set_client_name(name);
  h->set_client_id(client_id);
  d.phase = Impl::Phase::kAwaitWelcome;
  d.QueueLocked(Client::Impl::Frame(m), 0);
  const bool settled = d.cv.wait_for(lock, d.options.timeout, [&] {
    return d.phase != Impl::Phase::kAwaitWelcome || d.handshake_error.has_value();
  });
  if (d.handshake_error) return ErrorToStatus(*d.handshake_error);
  if (!settled) {
    return Status(Status::Code::kUnavailable, "no Welcome within " + Ms(d.options.timeout));
  }
  if (d.phase != Impl::Phase::kAuthed) {
    return Status(Status::Code::kUnavailable,
                  "connection lost before Welcome: " + d.disconnect_reason +
                      (d.options.tls.enabled
                           ? ""
                           : " (a server with TLS closes plaintext clients: connect with --tls "
                             "or ClientOptions::tls)"));
  }
  return d.welcome;
}

namespace {

// One JoinScene on the current connection. A Redirect answer closes the connection and is left
// in d.redirect for Join to follow.
// SceneInfo.cluster_members is the answering member's view, untrusted like any server input:
// an address that does not parse as HOST:PORT is skipped, and the list is bounded. A SceneInfo
// without members (a single process, or a member that has not read etcd yet) keeps what was
// learnt before.
void LearnMembersLocked(Client::Impl& d, const v1::SceneInfo& info) {
  std::vector<std::string> learnt;
  for (const v1::ClusterMember& m : info.cluster_members()) {
    if (learnt.size() >= kMaxLearntMembers) break;
    std::string host;
    uint16_t port = 0;
    if (m.tcp_address().size() > 300 || !ParseServerAddress(m.tcp_address(), &host, &port).ok()) {
      continue;
    }
    if (std::find(learnt.begin(), learnt.end(), m.tcp_address()) == learnt.end()) {
      learnt.push_back(m.tcp_address());
    }
  }
  if (!learnt.empty()) d.learnt_members = std::move(learnt);
}

// JoinScene.resends: the client_seq ranges of the pending requests (strokes, undos) this join
// is about to resend, oldest first, so the server lets them pass its rate limits without
// tokens. Strokes and undos share one counter, so each stream's range spans the other's
// sequences too; the ranges together stay within what the server allows a connection
// (limits.stroke_burst + 5 s of strokes; the client knows the rate from Welcome only, so
// 5 s of that). Pending requests past the bound are resent all the same, and charged.
void DeclareResendsLocked(const Client::Impl& d, v1::JoinScene* join) {
  const double rate = d.welcome.max_strokes_per_second();
  if (!(rate > 0) || d.pending.empty()) return;
  const uint64_t cap = static_cast<uint64_t>(std::min(kDeclaredResendSeconds * rate, 1e9));
  std::array<v1::ResendRange*, 2> ranges{};  // strokes, undos
  uint64_t declared = 0;
  for (const auto& [seq, p] : d.pending) {
    v1::ResendRange*& r = ranges[p.undo ? 1 : 0];
    const uint64_t cost = r ? seq - r->last_seq() : 1;
    if (declared + cost > cap) break;
    declared += cost;
    if (!r) {
      r = join->add_resends();
      r->set_stream(p.undo ? v1::EDIT_STREAM_UNDOS : v1::EDIT_STREAM_STROKES);
      r->set_first_seq(seq);
    }
    r->set_last_seq(seq);
  }
}

StatusOr<JoinedScene> JoinHere(Client::Impl& d, const std::string& scene) {
  std::unique_lock<std::mutex> lock(d.mu);
  if (d.phase == Client::Impl::Phase::kJoined) {
    return FailedPrecondition(
        "already joined on this connection (the server ignores a second "
        "JoinScene)");
  }
  if (d.phase != Client::Impl::Phase::kAuthed) {
    return FailedPrecondition("Join needs an authenticated connection: call Hello first");
  }
  d.handshake_error.reset();
  d.join_failure.reset();
  d.redirect.reset();
  d.join = JoinedScene{};
  v1::ClientMessage m;
  m.mutable_join()->set_scene(scene);
  m.mutable_join()->set_skip_state(d.options.skip_state);
  DeclareResendsLocked(d, m.mutable_join());
  d.phase = Client::Impl::Phase::kAwaitJoin;
  d.QueueLocked(Client::Impl::Frame(m), 0);
  const bool settled = d.cv.wait_for(lock, d.options.timeout, [&] {
    return d.phase != Client::Impl::Phase::kAwaitJoin || d.handshake_error || d.join_failure ||
           d.redirect;
  });
  if (d.redirect) {
    return Status(Status::Code::kUnavailable, "scene " + d.redirect->scene() +
                                                  " is owned by member " + d.redirect->member() +
                                                  " at " + d.redirect->tcp_address());
  }
  if (d.handshake_error) {
    if (d.phase == Client::Impl::Phase::kAwaitJoin) d.phase = Client::Impl::Phase::kAuthed;
    return ErrorToStatus(*d.handshake_error);
  }
  if (d.join_failure) {
    d.CloseConnLocked(d.conn, d.join_failure->message());
    return *d.join_failure;
  }
  if (!settled) {
    return Status(Status::Code::kUnavailable,
                  "no complete scene state within " + Ms(d.options.timeout));
  }
  if (d.phase != Client::Impl::Phase::kJoinComplete) {
    return Status(Status::Code::kUnavailable,
                  "connection lost while joining: " + d.disconnect_reason);
  }
  d.scene = scene;
  d.joined_once = true;
  d.scene_info = d.join.info;
  LearnMembersLocked(d, d.join.info);
  // Resends go out before new strokes, so every stroke reaches the server in client_seq order
  // (see the class comment). After a failover they are seconds of strokes. Those declared in the
  // JoinScene (DeclareResendsLocked) take none of the server's tokens, however the server reads
  // them; they still go out as a burst, then paced at 3/4 of the rate the server's Welcome
  // allows, so those past the declaration and the new owner's compute thread are not flooded;
  // requests made meanwhile queue behind them.
  for (auto& [seq, p] : d.pending) {
    if (p.written) ++(p.undo ? d.stats.undos_resent : d.stats.strokes_resent);
    p.written = false;
  }
  d.phase = Client::Impl::Phase::kJoined;
  d.resend_backlog = !d.pending.empty();
  if (d.resend_backlog) {
    const double rate = std::max(1.0, 0.75 * d.welcome.max_strokes_per_second());
    d.PaceResendsLocked(d.conn, kResendBurst,
                        std::chrono::microseconds(static_cast<int64_t>(1e6 / rate)));
  }
  return std::move(d.join);
}

}  // namespace

StatusOr<JoinedScene> Client::Join(const std::string& scene) {
  auto joined = JoinHere(*impl_, scene);
  std::string token, name;
  v1::Role role = v1::ROLE_UNSPECIFIED;
  uint64_t id = 0;
  v1::Redirect redirect;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (joined.ok() || !impl_->redirect) return joined;
    redirect = *std::exchange(impl_->redirect, std::nullopt);
    token = impl_->token;
    role = impl_->role;
    name = impl_->name;
    id = impl_->client_id;
    ++impl_->stats.redirects;
  }
  // Cluster mode: the member asked is not the scene's owner. One redirect is followed: a
  // second would mean the members disagree (an owner changing hands, or a forged answer).
  std::string host;
  uint16_t port = 0;
  if (!ParseServerAddress(redirect.tcp_address(), &host, &port).ok() || port == 0) {
    return Status(Status::Code::kUnavailable,
                  "redirected to an unusable address: Redirect.tcp_address=" +
                      redirect.tcp_address().substr(0, 128) + " (member " +
                      redirect.member().substr(0, 64) + ")");
  }
  SCULPT_RETURN_IF_ERROR(Connect(host, port));
  auto welcome = Hello(token, role, name, id);
  if (!welcome.ok()) return welcome.status();
  auto again = JoinHere(*impl_, scene);
  std::lock_guard<std::mutex> lock(impl_->mu);
  if (!again.ok() && impl_->redirect) {
    const v1::Redirect second = *std::exchange(impl_->redirect, std::nullopt);
    return Status(Status::Code::kUnavailable,
                  "redirected twice: member " + redirect.member() + " named the owner, which sent "
                  "this client on to member " + second.member().substr(0, 64) +
                  " (the members disagree about the owner; try again)");
  }
  return again;
}

Status Client::Reconnect() {
  std::string host, token, name, scene;
  uint16_t port = 0;
  v1::Role role = v1::ROLE_UNSPECIFIED;
  uint64_t id = 0;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (!impl_->joined_once) return FailedPrecondition("Reconnect needs a completed Join first");
    host = impl_->host;
    port = impl_->port;
    token = impl_->token;
    role = impl_->role;
    name = impl_->name;
    id = impl_->client_id;
    scene = impl_->scene;
    ++impl_->stats.reconnects;
  }
  auto rejoin = [&](const std::string& h, uint16_t p) -> Status {
    SCULPT_RETURN_IF_ERROR(Connect(h, p));
    auto welcome = Hello(token, role, name, id);
    if (!welcome.ok()) return welcome.status();
    auto joined = Join(scene);
    return joined.ok() ? Status::Ok() : joined.status();
  };
  Status s = rejoin(host, port);
  // Cluster mode: through any other member (it redirects to the owner) when the last server is
  // gone or cannot serve the scene now. Only for errors of reach, not for a refused token.
  // The members given first, then those the last join's SceneInfo listed (each tried once).
  std::vector<std::string> members = impl_->options.cluster_members;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    for (const std::string& m : impl_->learnt_members) {
      if (std::find(members.begin(), members.end(), m) == members.end()) members.push_back(m);
    }
  }
  std::vector<std::pair<std::string, uint16_t>> tried{{host, port}};
  for (const std::string& member : members) {
    if (s.ok() || s.code() != Status::Code::kUnavailable) break;
    std::string h;
    uint16_t p = 0;
    if (!ParseServerAddress(member, &h, &p).ok()) continue;
    if (std::find(tried.begin(), tried.end(), std::pair{h, p}) != tried.end()) continue;
    tried.emplace_back(h, p);
    s = rejoin(h, p);
  }
  return s;
}

StatusOr<uint64_t> Client::SendStroke(const StrokeRequest& stroke) {
  double voxel_size = 0;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (!impl_->joined_once) {
      return FailedPrecondition("SendStroke needs a joined scene (the voxel size packs poses)");
    }
    for (const v1::ObjectInfo& o : impl_->scene_info.objects()) {
      if (o.name() == stroke.object) voxel_size = o.voxel_size();
    }
  }
  if (voxel_size <= 0) {
    return NotFound("Stroke.object=" + stroke.object + " outside the scene's objects");
  }
  if (stroke.poses.empty()) return InvalidArgument("Stroke.pose_count=0 outside [1, max]");
  Vec3 lo = stroke.poses.front().position, hi = lo;
  for (const codec::Pose& p : stroke.poses) {
    lo = {std::min(lo.x, p.position.x), std::min(lo.y, p.position.y), std::min(lo.z, p.position.z)};
    hi = {std::max(hi.x, p.position.x), std::max(hi.y, p.position.y), std::max(hi.z, p.position.z)};
  }
  const Vec3 origin = (lo + hi) * 0.5;
  SCULPT_ASSIGN_OR_RETURN(std::string packed, codec::PackPoses(stroke.poses, origin, voxel_size));
  v1::Stroke s;
  s.set_object(stroke.object);
  s.set_kind(stroke.kind);
  s.set_tool(stroke.tool);
  *s.mutable_tool_size() = codec::ToProto(stroke.tool_size);
  s.set_speed(static_cast<float>(stroke.speed));
  s.set_amount(static_cast<float>(stroke.amount));
  *s.mutable_origin() = codec::ToProto(origin);
  s.set_t0_ms(stroke.t0_ms);
  s.set_pose_count(static_cast<uint32_t>(stroke.poses.size()));
  s.set_poses(std::move(packed));
  return SendStrokeMessage(std::move(s));
}

StatusOr<uint64_t> Client::SendStrokeMessage(v1::Stroke stroke) {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.mu);
  if (!d.joined_once) return FailedPrecondition("SendStroke needs a joined scene");
  if (d.pending.size() >= d.options.max_unacked) {
    return ResourceExhausted("un-acked strokes=" + std::to_string(d.pending.size()) +
                             " outside [0, " + std::to_string(d.options.max_unacked) + ")");
  }
  const uint64_t seq = d.next_seq++;
  stroke.set_client_seq(seq);
  v1::ClientMessage m;
  *m.mutable_stroke() = std::move(stroke);
  Impl::Pending& p = d.pending[seq];
  p.frame = Impl::Frame(m);
  p.sent_at = Clock::now();
  ++d.stats.strokes_sent;
  if (d.phase == Impl::Phase::kJoined && !d.resend_backlog) {
    p.written = true;
    d.QueueLocked(p.frame, seq);
  }
  return seq;
}

StatusOr<uint64_t> Client::SendUndo(const std::string& object, bool redo) {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.mu);
  const char* what = redo ? "Redo" : "Undo";
  if (!d.joined_once) return FailedPrecondition(std::string(what) + " needs a joined scene");
  std::string name = object;
  if (name.empty()) {
    if (d.scene_info.objects_size() == 0) {
      return InvalidArgument("UndoRequest.object=(none) outside the scene's objects: scene " +
                             d.scene_info.scene() + " has no objects");
    }
    name = d.scene_info.objects(0).name();
  } else {
    const auto& objects = d.scene_info.objects();
    if (std::none_of(objects.begin(), objects.end(),
                     [&](const v1::ObjectInfo& o) { return o.name() == name; })) {
      return NotFound("UndoRequest.object=" + name + " outside the scene's objects");
    }
  }
  if (d.pending.size() >= d.options.max_unacked) {
    return ResourceExhausted("un-acked strokes and undos=" + std::to_string(d.pending.size()) +
                             " outside [0, " + std::to_string(d.options.max_unacked) + ")");
  }
  const uint64_t seq = d.next_seq++;
  v1::ClientMessage m;
  v1::UndoRequest* u = m.mutable_undo();
  u->set_client_seq(seq);
  u->set_object(name);
  u->set_redo(redo);
  Impl::Pending& p = d.pending[seq];
  p.frame = Impl::Frame(m);
  p.sent_at = Clock::now();
  p.undo = true;
  p.redo = redo;
  ++d.stats.undos_sent;
  if (d.phase == Impl::Phase::kJoined && !d.resend_backlog) {
    p.written = true;
    d.QueueLocked(p.frame, seq);
  }
  return seq;
}

StatusOr<v1::UndoAck> Client::WaitUndoAck(uint64_t client_seq, std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  std::unique_lock<std::mutex> lock(d.mu);
  const auto waiting = [&] {
    auto it = d.pending.find(client_seq);
    return it != d.pending.end() && it->second.undo;
  };
  d.cv.wait_for(lock, timeout, [&] {
    return d.undo_answers.count(client_seq) > 0 || !waiting() ||
           d.phase == Impl::Phase::kDisconnected;
  });
  auto answer = d.undo_answers.find(client_seq);
  if (answer != d.undo_answers.end()) {
    v1::UndoAck a = std::move(answer->second);
    d.undo_answers.erase(answer);
    return a;
  }
  const std::string seq = std::to_string(client_seq);
  if (!waiting()) return NotFound("no undo request pending or answered with client_seq " + seq);
  if (d.phase == Impl::Phase::kDisconnected) {
    return Status(Status::Code::kUnavailable,
                  "connection lost before the UndoAck of client_seq " + seq + " (" +
                      d.disconnect_reason + "); it is resent by Reconnect()");
  }
  return Status(Status::Code::kUnavailable,
                "no UndoAck for client_seq " + seq + " within " + Ms(timeout));
}

namespace {

StatusOr<v1::UndoAck> UndoOrRedo(Client& client, const std::string& object, bool redo,
                                 std::chrono::milliseconds timeout) {
  SCULPT_ASSIGN_OR_RETURN(const uint64_t seq, client.SendUndo(object, redo));
  SCULPT_ASSIGN_OR_RETURN(v1::UndoAck ack, client.WaitUndoAck(seq, timeout));
  if (!ack.accepted()) return ErrorToStatus(ack.error());
  return ack;
}

}  // namespace

StatusOr<v1::UndoAck> Client::Undo(const std::string& object) {
  return UndoOrRedo(*this, object, /*redo=*/false, impl_->options.timeout);
}

StatusOr<v1::UndoAck> Client::Redo(const std::string& object) {
  return UndoOrRedo(*this, object, /*redo=*/true, impl_->options.timeout);
}

StatusOr<v1::HistoryAnswer> Client::History(const std::string& object, const std::string& author,
                                            uint32_t limit) {
  Impl& d = *impl_;
  std::unique_lock<std::mutex> lock(d.mu);
  if (d.phase != Impl::Phase::kJoined) return FailedPrecondition("History needs a joined scene");
  std::string name = object;
  if (name.empty()) {
    if (d.scene_info.objects_size() == 0) {
      return InvalidArgument("HistoryRequest.object=(none) outside the scene's objects: scene " +
                             d.scene_info.scene() + " has no objects");
    }
    name = d.scene_info.objects(0).name();
  }
  const uint64_t id = d.next_history_id++;
  v1::ClientMessage m;
  v1::HistoryRequest* h = m.mutable_history();
  h->set_request_id(id);
  h->set_object(name);
  h->set_author(author);
  h->set_limit(limit);
  d.history_waiting.insert(id);
  d.QueueLocked(Client::Impl::Frame(m), 0);
  const auto timeout = d.options.timeout;
  d.cv.wait_for(lock, timeout, [&] {
    return d.history_answers.count(id) > 0 || d.phase == Impl::Phase::kDisconnected;
  });
  d.history_waiting.erase(id);
  auto answer = d.history_answers.find(id);
  if (answer == d.history_answers.end()) {
    return Status(Status::Code::kUnavailable,
                  d.phase == Impl::Phase::kDisconnected
                      ? "connection lost before the HistoryAnswer (" + d.disconnect_reason + ")"
                      : "no HistoryAnswer within " + Ms(timeout));
  }
  v1::HistoryAnswer a = std::move(answer->second);
  d.history_answers.erase(answer);
  if (a.has_error()) return ErrorToStatus(a.error());
  return a;
}

Status Client::SendHover(const Vec3& position, double radius) {
  std::lock_guard<std::mutex> lock(impl_->mu);
  if (impl_->phase != Impl::Phase::kJoined) return FailedPrecondition("Hover needs a joined scene");
  v1::ClientMessage m;
  v1::Hover* h = m.mutable_hover();
  *h->mutable_position() = codec::ToProto(position);
  h->set_radius(static_cast<float>(radius));
  impl_->QueueLocked(Impl::Frame(m), 0);
  return Status::Ok();
}

bool Client::WaitAllAcked(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(impl_->mu);
  impl_->cv.wait_for(lock, timeout, [&] {
    return (impl_->pending.empty() || impl_->phase == Impl::Phase::kDisconnected) &&
           impl_->DeliveredLocked();
  });
  return impl_->pending.empty() && impl_->DeliveredLocked();
}

std::optional<Event> Client::NextEvent(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(impl_->mu);
  if (!impl_->cv.wait_for(lock, timeout, [&] { return !impl_->events.empty(); })) {
    return std::nullopt;
  }
  Event e = std::move(impl_->events.front());
  impl_->events.pop_front();
  return e;
}

std::vector<Event> Client::DrainEvents() {
  std::lock_guard<std::mutex> lock(impl_->mu);
  std::vector<Event> out(std::make_move_iterator(impl_->events.begin()),
                         std::make_move_iterator(impl_->events.end()));
  impl_->events.clear();
  return out;
}

void Client::SetReplicationHandler(std::function<void(v1::ServerMessage&&)> handler) {
  std::lock_guard<std::mutex> lock(impl_->mu);
  impl_->replication_handler = std::move(handler);
}

Status Client::SendMessage(const v1::ClientMessage& message) {
  std::lock_guard<std::mutex> lock(impl_->mu);
  if (impl_->phase != Impl::Phase::kJoined) {
    return FailedPrecondition("SendMessage needs a joined connection");
  }
  impl_->QueueLocked(Impl::Frame(message), 0);
  return Status::Ok();
}

void Client::SetEventHandler(EventHandler handler) {
  std::lock_guard<std::mutex> lock(impl_->handler_mu);
  impl_->handler = std::move(handler);
}

Status Client::Close(const std::string& reason) {
  std::unique_lock<std::mutex> lock(impl_->mu);
  return impl_->EndConnection(lock, reason, /*say_bye=*/true);
}

void Client::DropConnection() {
  std::unique_lock<std::mutex> lock(impl_->mu);
  (void)impl_->EndConnection(lock, "connection dropped by the client", /*say_bye=*/false);
}

bool Client::joined() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->phase == Impl::Phase::kJoined;
}

bool Client::connected() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->conn && !impl_->conn->closed;
}

size_t Client::unacked() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->pending.size();
}

std::vector<uint64_t> Client::UnackedSeqs() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  std::vector<uint64_t> out;
  out.reserve(impl_->pending.size());
  for (const auto& [seq, p] : impl_->pending) out.push_back(seq);
  return out;
}

uint64_t Client::client_id() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->client_id;
}

v1::Welcome Client::welcome() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->welcome;
}

std::vector<std::string> Client::learnt_members() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->learnt_members;
}

v1::SceneInfo Client::scene_info() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->scene_info;
}

ClientStats Client::stats() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->stats;
}

std::string ErrorCodeName(v1::ErrorCode code) {
  std::string name = v1::ErrorCode_Name(code);
  constexpr std::string_view kPrefix = "ERROR_CODE_";
  if (name.rfind(kPrefix, 0) == 0) name.erase(0, kPrefix.size());
  // A code newer than this client (enums only grow within version 1): its number.
  return name.empty() ? std::to_string(static_cast<int>(code)) : name;
}

Status ErrorToStatus(const v1::Error& error) {
  Status::Code code = Status::Code::kInternal;
  switch (error.code()) {
    case v1::ERROR_CODE_INVALID_ARGUMENT:
    case v1::ERROR_CODE_MALFORMED:
      code = Status::Code::kInvalidArgument;
      break;
    case v1::ERROR_CODE_NOT_FOUND:
      code = Status::Code::kNotFound;
      break;
    case v1::ERROR_CODE_RESOURCE_EXHAUSTED:
      code = Status::Code::kResourceExhausted;
      break;
    case v1::ERROR_CODE_UNAVAILABLE:
      code = Status::Code::kUnavailable;
      break;
    case v1::ERROR_CODE_UNAUTHENTICATED:
    case v1::ERROR_CODE_PERMISSION_DENIED:
    case v1::ERROR_CODE_FAILED_PRECONDITION:
    case v1::ERROR_CODE_VERSION_MISMATCH:
      code = Status::Code::kFailedPrecondition;
      break;
    default:
      code = Status::Code::kInternal;
      break;
  }
  std::string text = "ERROR_CODE_" + ErrorCodeName(error.code());
  if (!error.field().empty()) {
    text += " " + error.field() + "=" + error.value();
    if (!error.allowed_range().empty()) text += " outside " + error.allowed_range();
  }
  if (!error.message().empty()) text += ": " + error.message();
  return Status(code, text);
}

uint64_t NewClientId() {
  std::random_device rd;
  const uint64_t id = (uint64_t{rd()} << 32) ^ rd();
  // The top bit is the server's space for clients that send no id; never 0.
  const uint64_t masked = id & ~(uint64_t{1} << 63);
  return masked != 0 ? masked : 1;
}

uint64_t ClockClientSeq() {
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(
      std::chrono::system_clock::now().time_since_epoch());
  return std::max<int64_t>(1, us.count());
}

Status ParseServerAddress(const std::string& text, std::string* host, uint16_t* port) {
  const auto bad = [&text] {
    return InvalidArgument("--server=" + text + " outside HOST:PORT (port 1..65535)");
  };
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) return bad();
  std::string h = text.substr(0, colon);
  if (h.front() == '[') {
    if (h.size() < 3 || h.back() != ']') return bad();
    h = h.substr(1, h.size() - 2);
  }
  unsigned value = 0;
  const char* first = text.data() + colon + 1;
  const char* last = text.data() + text.size();
  const auto r = std::from_chars(first, last, value);
  if (r.ec != std::errc() || r.ptr != last || value == 0 || value > 65535) return bad();
  *host = h;
  *port = static_cast<uint16_t>(value);
  return Status::Ok();
}

StatusOr<JoinedScene> FetchScene(const std::string& address, const std::string& token,
                                 v1::Role role, const std::string& scene,
                                 std::chrono::milliseconds timeout, const ClientTlsOptions& tls) {
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseServerAddress(address, &host, &port));
  ClientOptions options;
  options.timeout = timeout;
  options.tls = tls;
  Client client(options);
  SCULPT_RETURN_IF_ERROR(client.Connect(host, port));
  auto welcome = client.Hello(token, role, "sculpt-cli", 0);
  if (!welcome.ok()) return welcome.status();
  auto joined = client.Join(scene);
  if (!joined.ok()) return joined.status();
  (void)client.Close("fetched the scene");
  return joined;
}

}  // namespace sculpt::client
