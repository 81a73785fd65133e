/// @brief Server: the TCP acceptor, the registry of live sessions and presence broadcasts.
#include "net/server.h"

#include <sodium.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "net/session.h"
#include "net/tcp_transport.h"
#include "net/tls.h"
#include "net/wire_error.h"
#include "sculpt/codec/shared_frame.h"

namespace sculpt::server {

namespace {

Authenticator::Options AuthOptions(const ServerConfig& c, bool with_users_file) {
  Authenticator::Options o;
  if (with_users_file) o.users_file = c.users_file;
  o.sculptor_token = c.sculptor_token;
  o.viewer_token = c.viewer_token;
  o.peer_token = c.cluster.peer_token;
  o.free_failures = c.limits.auth_free_failures;
  o.first_backoff = std::chrono::milliseconds(c.limits.auth_backoff_ms);
  return o;
}

}  // namespace

Server::Server(asio::io_context& io, const ServerConfig& config, std::vector<Scene*> scenes)
    : io_(io),
      config_(config),
      scenes_(std::move(scenes)),
      acceptor_(io),
      presence_timer_(io),
      accept_pause_(io, "accept on " + config.listen),
      budgets_(config.limits) {
  // A programmer's error (main opens at least scene.name): refused here, not at the first join.
  if (scenes_.empty() || std::find(scenes_.begin(), scenes_.end(), nullptr) != scenes_.end()) {
    throw std::invalid_argument("Server needs at least one scene and no null scene");
  }
  // The shared tokens until Start reads the users file (creating this one cannot fail).
  auto a = Authenticator::Create(AuthOptions(config_, false));
  if (a.ok()) auth_ = std::move(a).value();
}

Status Server::ReloadUsers() {
  if (!auth_) return FailedPrecondition("server not started");
  const Status s = auth_->Reload();
  if (s.ok()) {
    spdlog::info("users file {} reloaded: {} users", config_.users_file, auth_->user_count());
  } else {
    spdlog::error("users file not reloaded, the previous users stay: {}", s.ToString());
  }
  return s;
}

Server::~Server() { Stop(); }

StatusOr<uint16_t> Server::Start() {
  if (sodium_init() < 0) return Internal("libsodium failed to initialise");
  if (!config_.users_file.empty()) {
    auto a = Authenticator::Create(AuthOptions(config_, true));
    if (!a.ok()) return a.status();
    auth_ = std::move(a).value();
    spdlog::info("named users from {}: {}", config_.users_file, auth_->user_count());
  }
  if (!auth_) return Internal("no authenticator");
  if (config_.tls.enabled()) {
    auto tcp_ctx = MakeServerTlsContext(config_.tls, /*require_client_certs=*/true);
    if (!tcp_ctx.ok()) return tcp_ctx.status();
    auto http_ctx = MakeServerTlsContext(config_.tls, /*require_client_certs=*/false);
    if (!http_ctx.ok()) return http_ctx.status();
    tls_ = std::move(tcp_ctx).value();
    http_tls_ = std::move(http_ctx).value();
  } else if (!IsLoopbackListen(config_.listen)) {
    spdlog::warn("listening on {} beyond loopback WITHOUT TLS (tls.allow_plaintext): tokens and "
                 "strokes cross the network in clear",
                 config_.listen);
  }
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseHostPort(config_.listen, &host, &port));
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(host == "localhost" ? "127.0.0.1" : host, ec);
  if (ec) return InvalidArgument("listen host=" + host + " is not an IP address");
  const tcp::endpoint ep(address, port);
  acceptor_.open(ep.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(ep, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return Status(Status::Code::kUnavailable, "listen on " + config_.listen + ": " + ec.message());
  Accept();
  SchedulePresence();
  return acceptor_.local_endpoint().port();
}

void Server::Stop() {
  if (stopped_.exchange(true)) return;
  asio::post(io_, [this] {
    boost::system::error_code ec;
    acceptor_.close(ec);
    presence_timer_.cancel();
    accept_pause_.Cancel();
  });
  std::set<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    sessions = sessions_;
  }
  for (const auto& s : sessions) s->Shutdown("server shutting down");
}

void Server::Accept() {
  // Each connection gets its own strand; the socket is bound to it from the start.
  Strand strand = asio::make_strand(io_);
  acceptor_.async_accept(strand, [this, strand](boost::system::error_code ec, tcp::socket socket) {
    if (ec) {
      if (stopped_) return;
      if (ec == asio::error::operation_aborted) return Accept();
      stats_.accept_errors++;
      return accept_pause_.OnError(ec, [this] {
        if (!stopped_) Accept();
      });
    }
    accept_pause_.Succeeded();
    boost::system::error_code nd;
    socket.set_option(tcp::no_delay(true), nd);
    if (!tls_) {
      Adopt(strand,
            std::make_shared<TcpTransport>(std::move(socket), config_.limits.max_frame_bytes));
    } else {
      // The session starts once the handshake is done; a handshake that never completes
      // (plaintext, a silent peer) is cut at the authentication timeout.
      auto t = std::make_shared<TlsTcpTransport>(ssl::stream<tcp::socket>(std::move(socket), *tls_),
                                                 config_.limits.max_frame_bytes);
      t->AsyncHandshake(std::chrono::milliseconds(config_.limits.auth_timeout_ms),
                        [this, strand, t](Status st) {
                          if (!st.ok()) {
                            stats_.tls_handshake_failures++;
                            spdlog::info("tcp {}: {}", t->remote(), st.message());
                            return;
                          }
                          Adopt(strand, t);
                        });
    }
    if (!stopped_) Accept();
  });
}

bool Server::Adopt(Strand strand, std::shared_ptr<Transport> transport) {
  stats_.connections++;
  auto s = std::make_shared<Session>(*this, std::move(strand), std::move(transport),
                                     next_session_id_++);
  v1::Error refusal;
  switch (Register(s, &refusal)) {
    case Admission::kStopped:
      s->Shutdown("server shutting down");
      return false;
    case Admission::kRefused:
      // Logged once per interval: a flood of connections must not become a flood of lines.
      stats_.connections_refused++;
      if (const uint64_t n = refusal_log_.Tick()) {
        spdlog::warn("refused {} connection(s) since the last report; the latest from {}: {} "
                     "({} = {})",
                     n, s->source(), refusal.message(), refusal.field(), refusal.value());
      }
      s->Refuse(std::move(refusal));
      return true;
    case Admission::kAdmitted:
      break;
  }
  s->Start();
  return true;
}

Server::Admission Server::Register(const std::shared_ptr<Session>& s, v1::Error* refusal) {
  const LimitsConfig& l = config_.limits;
  std::lock_guard<std::mutex> lock(sessions_mu_);
  if (stopped_) return Admission::kStopped;
  if (sessions_.size() >= l.max_sessions) {
    *refusal = ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "limits.max_sessions",
                             std::to_string(sessions_.size()),
                             "[0, " + std::to_string(l.max_sessions) + "]",
                             "server full: too many connections");
    return Admission::kRefused;
  }
  const auto it = sessions_per_source_.find(s->source());
  const uint32_t from_source = it == sessions_per_source_.end() ? 0 : it->second;
  if (from_source >= l.max_connections_per_source) {
    *refusal = ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED,
                             "limits.max_connections_per_source", std::to_string(from_source),
                             "[0, " + std::to_string(l.max_connections_per_source) +
                                 "] per source address",
                             "too many connections from this address");
    return Admission::kRefused;
  }
  if (!s->ChargeConnection()) {
    *refusal = ProtocolError(v1::ERROR_CODE_RESOURCE_EXHAUSTED, "requests_per_second",
                             "a connection costs " + std::to_string(Session::kConnectionCost),
                             s->source_budget().AllowedRange(SharedBudget::Kind::kRequests) +
                                 " per source address",
                             "too many connections per second from this address");
    return Admission::kRefused;
  }
  sessions_.insert(s);
  ++sessions_per_source_[s->source()];
  return Admission::kAdmitted;
}

void Server::Unregister(const Session* s) {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  for (auto it = sessions_.begin(); it != sessions_.end(); ++it) {
    if (it->get() == s) {
      if (auto n = sessions_per_source_.find(s->source()); n != sessions_per_source_.end()) {
        if (--n->second == 0) sessions_per_source_.erase(n);
      }
      sessions_.erase(it);
      return;
    }
  }
}

Scene* Server::FindScene(const std::string& name) {
  for (Scene* scene : scenes_) {
    if (scene->name() == name) return scene;
  }
  return nullptr;
}

Server::Seats Server::JoinedSeats(const Scene& scene) {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  Seats seats;
  for (const auto& s : sessions_) {
    if (!s->joined() || s->joined_scene() != &scene) continue;
    ++seats.joined;
    if (s->role() == v1::ROLE_VIEWER) ++seats.viewers;
  }
  return seats;
}

Server::Seats Server::JoinedSeats() {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  Seats seats;
  for (const auto& s : sessions_) {
    if (!s->joined()) continue;
    ++seats.joined;
    if (s->role() == v1::ROLE_VIEWER) ++seats.viewers;
  }
  return seats;
}

uint32_t Server::SessionsFrom(const std::string& source) {
  std::lock_guard<std::mutex> lock(sessions_mu_);
  const auto it = sessions_per_source_.find(source);
  return it == sessions_per_source_.end() ? 0 : it->second;
}

SessionCounts Server::CountSessions() {
  SessionCounts counts;
  // Every label pair appears, also at zero, so a dashboard's series do not come and go.
  for (const char* role : {"unauthenticated", "sculptor", "viewer"}) {
    for (int t = 0; t < kTransportKinds; ++t) {
      counts[{role, TransportName(static_cast<TransportKind>(t))}] = 0;
    }
  }
  std::lock_guard<std::mutex> lock(sessions_mu_);
  for (const auto& s : sessions_) {
    const v1::Role r = s->role();
    const char* role = r == v1::ROLE_SCULPTOR ? "sculptor"
                       : r == v1::ROLE_VIEWER ? "viewer"
                                              : "unauthenticated";
    counts[{role, TransportName(s->transport_kind())}]++;
  }
  return counts;
}

void Server::SchedulePresence() {
  presence_timer_.expires_after(std::chrono::microseconds(
      static_cast<int64_t>(1e6 / std::max(0.1, config_.presence_hz))));
  presence_timer_.async_wait([this](boost::system::error_code ec) {
    if (ec || stopped_) return;
    BroadcastPresence();
    SchedulePresence();
  });
}

void Server::BroadcastPresence() {
  // Each scene's joined sessions, in the set's order (a single scene's broadcast is the one it
  // always was).
  std::map<const Scene*, std::vector<std::shared_ptr<Session>>> by_scene;
  {
    std::lock_guard<std::mutex> lock(sessions_mu_);
    for (const auto& s : sessions_) {
      if (s->joined()) by_scene[s->joined_scene()].push_back(s);
    }
  }
  for (const auto& [scene, sessions] : by_scene) {
    if (sessions.size() < 2) continue;
    v1::ServerMessage msg;
    for (const auto& s : sessions) *msg.mutable_presence()->add_users() = s->PresenceEntry();
    // Serialized once, shared by every session of the scene.
    const Frame frame = codec::EncodeSharedFrame(msg);
    for (const auto& s : sessions) s->DeliverPresence(frame);
  }
}

}  // namespace sculpt::server
