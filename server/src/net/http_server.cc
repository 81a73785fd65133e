/// @brief HttpServer: static files, /ws, /metrics, /healthz, /readyz on Boost.Beast.
#include "net/http_server.h"

#include <spdlog/spdlog.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <functional>
#include <optional>
#include <type_traits>
#include <vector>

#include "net/beast.h"
#include "net/metrics.h"
#include "net/tls.h"
#include "net/ws_transport.h"
#include "store/recovery.h"

namespace sculpt::server {
namespace {

// The page may load only its own scripts, styles, images and WebAssembly; three.js's Draco
// decoder runs in workers made from Blob URLs and compiles WebAssembly ('wasm-unsafe-eval').
// 'self' in connect-src covers the same-origin ws:// of /ws.
constexpr char kContentSecurityPolicy[] =
    "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; worker-src 'self' blob:; "
    "connect-src 'self'; img-src 'self' data: blob:; style-src 'self'; object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'none'";
// The policy with each --http-allow-origin also allowed in connect-src (as http(s):// and
// ws(s)://): in a cluster those are the other members, and a page served here follows a Redirect
// by opening /ws on the scene's owner. An origin with characters outside a plain
// scheme://host:port is left out (it could otherwise add directives).
std::string ContentSecurityPolicy(const std::vector<std::string>& allowed_origins) {
  std::string extra;
  for (const std::string& o : allowed_origins) {
    const bool plain = std::all_of(o.begin(), o.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == ':' || c == '/' || c == '.' ||
             c == '-' || c == '[' || c == ']';
    });
    if (!plain) continue;
    if (o.rfind("http://", 0) == 0) {
      extra += " " + o + " ws://" + o.substr(7);
    } else if (o.rfind("https://", 0) == 0) {
      extra += " " + o + " wss://" + o.substr(8);
    }
  }
  std::string csp = kContentSecurityPolicy;
  const std::string self = "connect-src 'self'";
  csp.insert(csp.find(self) + self.size(), extra);
  return csp;
}
// Requests carry no body here; a small one is read and ignored (then answered 405).
constexpr uint64_t kMaxRequestBodyBytes = 16 * 1024;
// After an error response the rest of the request is read and dropped for this long, so the
// client sees the response instead of a reset.
constexpr auto kLingerTime = std::chrono::milliseconds(500);

using Request = http::request<http::string_body>;
using Response = http::response<http::string_body>;

bool IsHttpParseError(const beast::error_code& ec) {
  return ec.category() == http::make_error_code(http::error::bad_target).category();
}

std::string_view PathOf(beast::string_view target) {
  std::string_view t(target.data(), target.size());
  const size_t q = t.find_first_of("?#");
  return q == std::string_view::npos ? t : t.substr(0, q);
}

}  // namespace

bool OriginAllowed(std::string_view origin, std::string_view host,
                   const std::vector<std::string>& allowed) {
  if (origin.empty()) return true;
  for (const std::string& a : allowed) {
    if (origin == a) return true;
  }
  // "scheme://host[:port]": the page's own origin names the Host it was served from.
  const size_t sep = origin.find("://");
  if (sep == std::string_view::npos || host.empty()) return false;
  return origin.substr(sep + 3) == host;
}

/// An HTTP connection as the server's list of open ones sees it.
class HttpServer::Connection {
 public:
  virtual ~Connection() = default;
  /// Closes the connection (from any thread).
  virtual void Stop() = 0;
};

/// One HTTP connection until it closes or becomes a WebSocket session; `Stream` is a
/// beast::tcp_stream or a beast::ssl_stream over one (HTTPS). Every member is touched only on
/// its strand.
template <class Stream>
class HttpServer::BasicConnection final
    : public HttpServer::Connection,
      public std::enable_shared_from_this<HttpServer::BasicConnection<Stream>> {
 public:
  static constexpr bool kTls = !std::is_same_v<Stream, beast::tcp_stream>;

  BasicConnection(HttpServer& owner, Strand strand, Stream stream, std::shared_ptr<void> slot)
      : owner_(owner),
        strand_(std::move(strand)),
        stream_(std::move(stream)),
        slot_(std::move(slot)),
        stats_(owner.stats_) {}

  void Start() {
    asio::dispatch(strand_, [self = this->shared_from_this()] {
      if constexpr (kTls) {
        self->Handshake();
      } else {
        self->DoRead();
      }
    });
  }

  void Stop() override {
    asio::post(strand_, [self = this->shared_from_this()] {
      beast::error_code ec;
      self->Lowest().socket().shutdown(tcp::socket::shutdown_both, ec);
      self->Lowest().close();
    });
  }

 private:
  beast::tcp_stream& Lowest() { return beast::get_lowest_layer(stream_); }

  // HTTPS: the handshake first, bounded by the authentication timeout (a peer that never
  // completes it, or speaks plain HTTP, is closed).
  void Handshake() {
    const int timeout_ms = owner_.server_.config().limits.auth_timeout_ms;
    Lowest().expires_after(std::chrono::milliseconds(timeout_ms));
    stream_.async_handshake(
        ssl::stream_base::server,
        [self = this->shared_from_this(), timeout_ms](beast::error_code ec) {
          if (ec) {
            self->stats_->tls_handshake_failures++;
            spdlog::info("http {}: TLS handshake: {}", self->Remote(),
                         ec == beast::error::timeout
                             ? "not complete within " + std::to_string(timeout_ms) + " ms"
                             : DescribeHandshakeError(ec));
            return self->Lowest().close();
          }
          self->DoRead();
        });
  }

  std::string Remote() {
    boost::system::error_code ec;
    const auto ep = Lowest().socket().remote_endpoint(ec);
    return ec ? "?" : ep.address().to_string() + ":" + std::to_string(ep.port());
  }

  void DoRead() {
    parser_.emplace();
    parser_->header_limit(owner_.config_.max_header_bytes);
    parser_->body_limit(kMaxRequestBodyBytes);
    Lowest().expires_after(std::chrono::milliseconds(owner_.config_.idle_timeout_ms));
    http::async_read(stream_, buffer_, *parser_,
                     [self = this->shared_from_this()](beast::error_code ec, size_t) {
                       self->OnRead(ec);
                     });
  }

  void OnRead(beast::error_code ec) {
    if (ec == http::error::end_of_stream) return Shutdown();
    if (ec == beast::error::timeout) {
      stats_->idle_timeouts++;
      return Shutdown();
    }
    if (ec == http::error::header_limit) {
      return SendError(http::status::request_header_fields_too_large,
                       "request headers above " +
                           std::to_string(owner_.config_.max_header_bytes) + " bytes\n",
                       /*close=*/true);
    }
    if (ec == http::error::body_limit) {
      return SendError(http::status::payload_too_large, "request body not accepted\n", true);
    }
    if (ec) {
      if (IsHttpParseError(ec)) {
        return SendError(http::status::bad_request, "bad request: " + ec.message() + "\n", true);
      }
      return Shutdown();  // the connection failed: nothing to answer
    }
    Route(parser_->release());
  }

  void Route(Request req) {
    const std::string_view path = PathOf(req.target());
    const bool get_or_head = req.method() == http::verb::get || req.method() == http::verb::head;
    if (path == "/ws") {
      if (req.method() != http::verb::get) return MethodNotAllowed(req, "GET");
      if (!websocket::is_upgrade(req)) {
        Response res = Make(req, http::status::upgrade_required, "text/plain; charset=utf-8",
                            "/ws is a WebSocket: one sculpt.v1 message per binary message\n");
        res.set(http::field::upgrade, "websocket");
        return Send(req, std::move(res));
      }
      const auto origin = req.find(http::field::origin);
      const auto host = req.find(http::field::host);
      auto sv = [](beast::string_view v) { return std::string_view(v.data(), v.size()); };
      if (!OriginAllowed(origin == req.end() ? "" : sv(origin->value()),
                         host == req.end() ? "" : sv(host->value()),
                         owner_.config_.allowed_origins)) {
        return Send(req, Make(req, http::status::forbidden, "text/plain; charset=utf-8",
                              "WebSocket from origin " + std::string(sv(origin->value())) +
                                  " refused: only the page's own origin (or --http-allow-origin)\n"));
      }
      return Upgrade(std::move(req));
    }
    if (!get_or_head) return MethodNotAllowed(req, "GET, HEAD");
    if (path == "/healthz") {
      return Send(req, Make(req, http::status::ok, "text/plain; charset=utf-8", "ok\n"));
    }
    if (path == "/readyz") {
      const Status ready = owner_.Readiness();
      return Send(req, Make(req, ready.ok() ? http::status::ok : http::status::service_unavailable,
                            "text/plain; charset=utf-8",
                            ready.ok() ? "ready\n" : "not ready: " + ready.message() + "\n"));
    }
    if (path == "/metrics") {
      return Send(req, Make(req, http::status::ok, "text/plain; version=0.0.4; charset=utf-8",
                            owner_.MetricsText()));
    }
    auto file = owner_.files_.Lookup(std::string_view(req.target().data(), req.target().size()));
    if (!file.ok()) {
      const Status& st = file.status();
      const http::status code = st.code() == Status::Code::kInvalidArgument
                                    ? http::status::bad_request
                                : st.code() == Status::Code::kNotFound ? http::status::not_found
                                                                       : http::status::internal_server_error;
      return Send(req, Make(req, code, "text/plain; charset=utf-8", st.message() + "\n"));
    }
    const auto inm = req.find(http::field::if_none_match);
    if (inm != req.end() && inm->value() == file->etag) {
      Response res = Make(req, http::status::not_modified, "", "");
      res.set(http::field::etag, file->etag);
      res.set(http::field::cache_control, file->cache_control);
      return Send(req, std::move(res));
    }
    Response res = Make(req, http::status::ok, file->content_type, std::move(file->body));
    res.set(http::field::etag, file->etag);
    res.set(http::field::cache_control, file->cache_control);
    Send(req, std::move(res));
  }

  Response Make(const Request& req, http::status status, std::string_view type, std::string body) {
    Response res{status, req.version()};
    res.set(http::field::server, "sculptd");
    if (!type.empty()) res.set(http::field::content_type, beast::string_view(type.data(), type.size()));
    res.set("Content-Security-Policy", owner_.csp_);
    res.set("X-Content-Type-Options", "nosniff");
    res.set("Referrer-Policy", "no-referrer");
    if (status != http::status::ok && status != http::status::not_modified) {
      res.set(http::field::cache_control, "no-store");
    }
    res.keep_alive(req.keep_alive());
    res.body() = std::move(body);
    return res;
  }

  void MethodNotAllowed(const Request& req, const char* allow) {
    Response res = Make(req, http::status::method_not_allowed, "text/plain; charset=utf-8",
                        std::string(req.method_string()) + " not allowed; use " + allow + "\n");
    res.set(http::field::allow, allow);
    Send(req, std::move(res));
  }

  void Send(const Request& req, Response res) {
    const bool head = req.method() == http::verb::head;
    if (res.result() == http::status::not_modified) {
      res.content_length(boost::none);
    } else {
      res.prepare_payload();
    }
    owner_.CountResponse(static_cast<int>(res.result_int()));
    const bool close = !res.keep_alive();
    if (head) {
      // The headers of a GET, without the body.
      auto h = std::make_shared<http::response<http::empty_body>>(res.base());
      return Write(std::move(h), close);
    }
    Write(std::make_shared<Response>(std::move(res)), close);
  }

  void SendError(http::status status, std::string text, bool close) {
    Response res{status, 11};
    res.set(http::field::server, "sculptd");
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(!close);
    res.body() = std::move(text);
    res.prepare_payload();
    owner_.CountResponse(static_cast<int>(res.result_int()));
    auto sp = std::make_shared<Response>(std::move(res));
    Lowest().expires_after(kLingerTime);
    http::async_write(stream_, *sp, [self = this->shared_from_this(), sp](beast::error_code ec, size_t) {
      if (ec) return self->Shutdown();
      self->Linger();
    });
  }

  template <class Message>
  void Write(std::shared_ptr<Message> msg, bool close) {
    Lowest().expires_after(std::chrono::milliseconds(owner_.config_.idle_timeout_ms));
    http::async_write(stream_, *msg,
                      [self = this->shared_from_this(), msg, close](beast::error_code ec, size_t) {
                        if (ec || close) return self->Shutdown();
                        self->DoRead();
                      });
  }

  // Half-closes, then reads and drops what the client still sends until it closes or the
  // linger time passes, so an error response is not lost to a reset.
  void Linger() {
    beast::error_code ec;
    Lowest().socket().shutdown(tcp::socket::shutdown_send, ec);
    Lowest().expires_after(kLingerTime);
    stream_.async_read_some(asio::buffer(drain_),
                            [self = this->shared_from_this()](beast::error_code ec, size_t) {
                              if (ec) return self->Lowest().close();
                              self->LingerMore();
                            });
  }
  void LingerMore() {
    stream_.async_read_some(asio::buffer(drain_),
                            [self = this->shared_from_this()](beast::error_code ec, size_t) {
                              if (ec) return self->Lowest().close();
                              self->LingerMore();
                            });
  }

  void Shutdown() {
    beast::error_code ec;
    Lowest().socket().shutdown(tcp::socket::shutdown_send, ec);
    Lowest().close();
  }

  void Upgrade(Request req) {
    Lowest().expires_never();
    std::string remote = Remote();
    using Ws = BasicWsTransport<Stream>;
    auto ws = std::make_unique<typename Ws::Stream>(std::move(stream_));
    ws->set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    websocket::permessage_deflate pmd;
    pmd.server_enable = false;
    pmd.client_enable = false;
    ws->set_option(pmd);
    ws->set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "sculptd"); }));
    auto request = std::make_shared<Request>(std::move(req));
    typename Ws::Stream* raw = ws.get();
    raw->async_accept(*request, [self = this->shared_from_this(), request, ws = std::move(ws),
                                 remote = std::move(remote)](beast::error_code ec) mutable {
      if (ec) {
        spdlog::info("websocket upgrade from {} failed: {}", remote, ec.message());
        return;
      }
      self->stats_->websocket_upgrades++;
      self->owner_.CountResponse(101);
      auto transport = std::make_shared<Ws>(
          std::move(ws), std::move(remote), self->owner_.server_.config().limits.max_frame_bytes,
          std::move(self->slot_));
      self->owner_.server_.Adopt(self->strand_, std::move(transport));
    });
  }

  HttpServer& owner_;
  Strand strand_;
  Stream stream_;
  std::shared_ptr<void> slot_;
  std::shared_ptr<HttpStats> stats_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::array<char, 4096> drain_{};
};

HttpServer::HttpServer(asio::io_context& io, HttpConfig config, Server& server)
    : io_(io),
      config_(std::move(config)),
      server_(server),
      files_(config_.web_root),
      acceptor_(io),
      accept_pause_(io, "http accept on " + config_.listen),
      csp_(ContentSecurityPolicy(config_.allowed_origins)) {}

HttpServer::~HttpServer() { Stop(); }

StatusOr<uint16_t> HttpServer::Start() {
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseHostPort(config_.listen, &host, &port));
  tls_ = server_.http_tls_context();
  if (!tls_ && !IsLoopbackListen(config_.listen)) {
    if (!server_.config().tls.allow_plaintext) {
      return InvalidArgument("http listen=" + config_.listen +
                             " is beyond loopback without TLS: set tls.cert_file and "
                             "tls.key_file (--tls-cert, --tls-key), or tls.allow_plaintext = true "
                             "(--allow-plaintext)");
    }
    spdlog::warn("http on {} beyond loopback WITHOUT TLS (tls.allow_plaintext): tokens and "
                 "strokes cross the network in clear",
                 config_.listen);
  }
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(host == "localhost" ? "127.0.0.1" : host, ec);
  if (ec) return InvalidArgument("http host=" + host + " is not an IP address");
  const tcp::endpoint ep(address, port);
  acceptor_.open(ep.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(ep, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return Status(Status::Code::kUnavailable,
                  "http listen on " + config_.listen + ": " + ec.message() +
                      " (choose another with --http HOST:PORT, port 0 picks a free one)");
  }
  if (!files_.root_exists()) {
    spdlog::warn("web root {} does not exist: GET / answers 404 (build client/web or pass "
                 "--web-root)",
                 config_.web_root.string());
  }
  Accept();
  return acceptor_.local_endpoint().port();
}

void HttpServer::Stop() {
  if (stopped_.exchange(true)) return;
  asio::post(io_, [this] {
    boost::system::error_code ec;
    acceptor_.close(ec);
    accept_pause_.Cancel();
  });
  std::lock_guard<std::mutex> lock(connections_mu_);
  for (auto& [id, weak] : connections_) {
    if (auto c = weak.lock()) c->Stop();
  }
  connections_.clear();
}

void HttpServer::Accept() {
  Strand strand = asio::make_strand(io_);
  acceptor_.async_accept(strand, [this, strand](boost::system::error_code ec, tcp::socket socket) {
    if (ec) {
      if (stopped_) return;
      if (ec == asio::error::operation_aborted) return Accept();
      // Out of descriptors: pause instead of spinning (net/accept_pause.h).
      return accept_pause_.OnError(ec, [this] {
        if (!stopped_) Accept();
      });
    }
    accept_pause_.Succeeded();
    if (static_cast<size_t>(open_->load()) >= config_.max_connections) {
      // Full: a short answer without waiting on the client, then close. The connections
      // already open, and every TCP session, are not touched.
      stats_->connections_refused++;
      CountResponse(503);
      static constexpr char kBusy[] =
          "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
      boost::system::error_code wec;
      socket.non_blocking(true, wec);
      socket.write_some(asio::buffer(kBusy, sizeof kBusy - 1), wec);
      socket.close(wec);
    } else {
      stats_->connections_accepted++;
      open_->fetch_add(1);
      std::shared_ptr<void> slot(nullptr, [open = open_](void*) { open->fetch_sub(1); });
      boost::system::error_code nd;
      socket.set_option(tcp::no_delay(true), nd);
      std::shared_ptr<Connection> c;
      std::function<void()> start;
      if (tls_) {
        auto tc = std::make_shared<BasicConnection<beast::ssl_stream<beast::tcp_stream>>>(
            *this, strand,
            beast::ssl_stream<beast::tcp_stream>(beast::tcp_stream(std::move(socket)), *tls_),
            std::move(slot));
        c = tc;
        start = [tc] { tc->Start(); };
      } else {
        auto pc = std::make_shared<BasicConnection<beast::tcp_stream>>(
            *this, strand, beast::tcp_stream(std::move(socket)), std::move(slot));
        c = pc;
        start = [pc] { pc->Start(); };
      }
      {
        std::lock_guard<std::mutex> lock(connections_mu_);
        // Forget connections that have ended, so the map stays as small as the open set.
        for (auto it = connections_.begin(); it != connections_.end();) {
          it = it->second.expired() ? connections_.erase(it) : std::next(it);
        }
        connections_[next_connection_++] = c;
      }
      start();
    }
    if (!stopped_) Accept();
  });
}

void HttpServer::CountResponse(int code) {
  std::lock_guard<std::mutex> lock(stats_->responses_mu);
  stats_->responses[code]++;
}

Status HttpServer::Readiness() {
  if (stopped_) return Status(Status::Code::kUnavailable, "shutting down");
  // Every hosted scene's log: one that cannot take edits makes the process not ready.
  for (const Scene* scene : server_.scenes()) {
    const std::filesystem::path log_dir =
        std::filesystem::path(SceneDataDir(server_.config(), scene->name())) / store::kLogSubdir;
    if (::access(log_dir.c_str(), W_OK) != 0) {
      return Status(Status::Code::kUnavailable, "edit log directory " + log_dir.string() +
                                                    " is not writable");
    }
    struct statvfs fs {};
    if (::statvfs(log_dir.c_str(), &fs) == 0 &&
        static_cast<uint64_t>(fs.f_bavail) * fs.f_frsize < (1u << 20)) {
      return Status(Status::Code::kUnavailable,
                    "edit log directory " + log_dir.string() + " has under 1 MiB free");
    }
  }
  return Status::Ok();
}

std::string HttpServer::MetricsText() {
  MetricsWriter w;
  ServerStats& s = server_.stats();
  // A process hosting several scenes (docs/scenes.md) labels each scene's figures with its name;
  // one hosting a single scene writes them unlabelled, as it always did.
  const std::vector<Scene*>& scenes = server_.scenes();
  auto per_scene = [&](const std::function<void(Scene&, const MetricLabels&)>& write) {
    for (Scene* scene : scenes) {
      MetricLabels labels;
      if (scenes.size() > 1) labels.emplace_back("scene", scene->name());
      write(*scene, labels);
    }
  };
  // `labels` with one more pair after the scene's.
  auto with = [](MetricLabels labels, std::string key, std::string value) {
    labels.emplace_back(std::move(key), std::move(value));
    return labels;
  };
  for (const auto& [key, n] : server_.CountSessions()) {
    w.Gauge("sculpt_sessions", "Live sessions by role and transport", static_cast<double>(n),
            {{"role", key.first}, {"transport", key.second}});
  }
  w.Counter("sculpt_connections_total", "Client connections accepted (TCP and WebSocket)",
            static_cast<double>(s.connections.load()));
  w.Counter("sculpt_strokes_accepted_total",
            "Edits acknowledged (strokes, paints, model intents; duplicates not counted "
            "twice); rate() gives strokes per second",
            static_cast<double>(s.strokes_accepted.load()));
  w.Counter("sculpt_strokes_refused_total", "Edits refused (validation, role, rate limit)",
            static_cast<double>(s.strokes_refused.load()));
  w.Counter("sculpt_errors_sent_total", "Error messages sent to clients",
            static_cast<double>(s.errors_sent.load()));
  w.Counter("sculpt_disconnects_for_cause_total",
            "Clients dropped for rate violations or a full send queue",
            static_cast<double>(s.disconnects_for_cause.load()));
  per_scene([&](Scene& scene, const MetricLabels& labels) {
    w.Counter("sculpt_edits_total",
              "Edits applied to the scene (its global sequence, since the data directory "
              "began); rate() gives edits per second",
              static_cast<double>(scene.global_seq()), labels);
  });
  // One family at a time: the text format wants each family's samples together.
  auto per_transport = [&](const char* name, const char* help,
                           const std::array<std::atomic<uint64_t>, kTransportKinds>& values) {
    for (int t = 0; t < kTransportKinds; ++t) {
      w.Counter(name, help, static_cast<double>(values[t].load()),
                {{"transport", TransportName(static_cast<TransportKind>(t))}});
    }
  };
  per_transport("sculpt_received_bytes_total", "Bytes read from clients", s.bytes_in);
  per_transport("sculpt_sent_bytes_total", "Bytes written to clients", s.bytes_out);
  per_transport("sculpt_received_messages_total", "Client messages received", s.messages_in);
  for (int t = 0; t < kTransportKinds; ++t) {
    w.Histogram("sculpt_stroke_ack_seconds",
                "From a stroke's arrival to its acknowledgement (logged durably and applied)",
                s.stroke_ack_seconds[t].Read(),
                {{"transport", TransportName(static_cast<TransportKind>(t))}});
  }
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_replication_broadcasts_total", "Edit broadcasts built for replicas",
              static_cast<double>(sc.replication_stats().broadcasts.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_replication_leaf_deltas_total", "Leaf-delta messages built for replicas",
              static_cast<double>(sc.replication_stats().leaf_deltas.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_replication_resyncs_total", "Replica region loads (subscribe, interest)",
              static_cast<double>(sc.replication_stats().resyncs.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_replication_divergences_total", "Replicas' reports of a state-hash mismatch",
              static_cast<double>(sc.replication_stats().divergences.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    ReplicationStats& r = sc.replication_stats();
    w.Counter("sculpt_replication_bytes_total", "Bytes of replication messages built",
              static_cast<double>(r.broadcast_bytes.load()), with(l, "kind", "broadcast"));
    w.Counter("sculpt_replication_bytes_total", "Bytes of replication messages built",
              static_cast<double>(r.leaf_delta_bytes.load()), with(l, "kind", "leaf_delta"));
  });
  w.Counter("sculpt_viewer_chunks_superseded_total",
            "Mesh chunk frames a slow viewer never got because a newer version replaced them",
            static_cast<double>(s.frames_superseded.load()));
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_viewer_chunk_encodes_total", "Mesh chunks Draco-encoded for viewers",
              static_cast<double>(sc.mesh_stats().chunks_encoded.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_viewer_chunk_bytes_total", "Bytes of encoded mesh chunk messages",
              static_cast<double>(sc.mesh_stats().chunk_bytes.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_viewer_mesh_updates_total", "Viewer mesh update rounds",
              static_cast<double>(sc.mesh_stats().updates.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_viewer_snapshot_seconds_total",
              "Compute-thread time spent copying sculptures for the mesher",
              static_cast<double>(sc.mesh_stats().snapshot_us.load()) * 1e-6, l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Histogram("sculpt_log_fsync_seconds",
                "Durations of the edit log's fdatasync calls, each making the records written "
                "before it durable (acknowledgements wait for them)",
                sc.log_sync_seconds(), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Gauge("sculpt_compute_queue_depth",
            "Tasks queued for the scene's compute thread and not yet started (edits, joins, "
            "subscriptions)",
            static_cast<double>(sc.compute_queue_depth()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Gauge("sculpt_acks_awaiting_durability",
            "Edits applied whose acknowledgement waits for the edit log's next fdatasync",
            static_cast<double>(sc.acks_awaiting_durability()), l);
  });
  // Cluster mode with replication = "sync" (docs/cluster.md).
  per_scene([&](Scene& sc, const MetricLabels& l) {
    if (!sc.acks().sync()) return;
    w.Gauge("sculpt_replication_sync_fallen_back",
            "1 while acknowledgements do not wait for the standby (it did not confirm an edit "
            "within cluster.sync_fallback_ms), 0 while they do",
            sc.acks().fallen_back() ? 1.0 : 0.0, l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    if (!sc.acks().sync()) return;
    w.Counter("sculpt_replication_sync_fallbacks_total",
              "Times synchronous replication fell back to asynchronous",
              static_cast<double>(sc.acks().fallbacks()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    if (!sc.acks().sync()) return;
    w.Gauge("sculpt_replication_standby_durable_seq",
            "The last sequence the standby said its copy holds durably",
            static_cast<double>(sc.acks().standby_durable_seq()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_compute_task_failures_total",
              "Scene tasks that threw (compute thread and join worker: the requester got "
              "INTERNAL; mesher: the chunk was skipped)",
              static_cast<double>(sc.task_stats().failures.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Gauge("sculpt_late_joins_pending",
            "Late joins admitted and not yet answered (copying, queued or being serialised)",
            static_cast<double>(sc.pending_joins()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_late_joins_refused_total",
              "Late joins refused over limits.max_pending_joins (RESOURCE_EXHAUSTED)",
              static_cast<double>(sc.task_stats().joins_refused.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Counter("sculpt_compute_jobs_passed_over_total",
              "Times the compute thread served a client's job while an older job of another "
              "client (user or source address) waited (fair sharing by measured cost)",
              static_cast<double>(sc.task_stats().passed_over.load()), l);
  });
  per_scene([&](Scene& sc, const MetricLabels& l) {
    w.Gauge("sculpt_compute_waiting_sessions",
            "Clients (users or source addresses) with work queued for the scene's compute thread",
            static_cast<double>(sc.task_stats().waiting_sessions.load()), l);
  });
  w.Gauge("sculpt_http_connections", "Open HTTP connections and WebSocket sessions",
          static_cast<double>(open_->load()));
  w.Counter("sculpt_http_connections_refused_total",
            "HTTP connections refused at the connection limit",
            static_cast<double>(stats_->connections_refused.load()));
  w.Counter("sculpt_http_idle_timeouts_total", "HTTP connections closed for idleness",
            static_cast<double>(stats_->idle_timeouts.load()));
  w.Counter("sculpt_tls_handshake_failures_total",
            "TLS handshakes that failed or timed out (plaintext, bad certificates)",
            static_cast<double>(s.tls_handshake_failures.load()), {{"port", "tcp"}});
  w.Counter("sculpt_tls_handshake_failures_total",
            "TLS handshakes that failed or timed out (plaintext, bad certificates)",
            static_cast<double>(stats_->tls_handshake_failures.load()), {{"port", "http"}});
  {
    std::lock_guard<std::mutex> lock(stats_->responses_mu);
    for (const auto& [code, n] : stats_->responses) {
      w.Counter("sculpt_http_responses_total", "HTTP responses by status code",
                static_cast<double>(n), {{"code", std::to_string(code)}});
    }
  }
  w.Gauge("sculpt_uptime_seconds", "Seconds since the HTTP port opened",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count());
  {
    std::lock_guard<std::mutex> lock(sources_mu_);
    for (const auto& source : sources_) source(w);
  }
  return w.text();
}

void HttpServer::AddMetricsSource(std::function<void(MetricsWriter&)> source) {
  std::lock_guard<std::mutex> lock(sources_mu_);
  sources_.push_back(std::move(source));
}

}  // namespace sculpt::server
