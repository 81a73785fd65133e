/// @brief HttpServer: sculptd's HTTP port: the web client's files, the /ws WebSocket (the same
/// sessions as TCP), /metrics (Prometheus text), /healthz and /readyz.
#ifndef SCULPT_SERVER_NET_HTTP_SERVER_H_
#define SCULPT_SERVER_NET_HTTP_SERVER_H_

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "net/metrics.h"
#include "net/accept_pause.h"
#include "net/net.h"
#include "net/server.h"
#include "net/static_files.h"

namespace sculpt::server {

/// The HTTP port's settings (flags of `sculptd serve`).
struct HttpConfig {
  std::string listen = "127.0.0.1:7421";
  /// The web client's files; a missing directory answers 404 naming it.
  std::filesystem::path web_root;
  /// Open HTTP connections and WebSocket sessions together; past it a connection gets 503 and
  /// is closed at once (the TCP port is not affected).
  size_t max_connections = 512;
  /// A connection that sends no complete request for this long is closed.
  int idle_timeout_ms = 15000;
  /// Request line plus headers; larger requests get 431.
  uint32_t max_header_bytes = 8192;
  /// Origins besides the page's own that may open /ws ("http://localhost:5173" for a dev
  /// server). A browser upgrade from any other origin gets 403; clients that send no Origin
  /// (native ones) are not affected.
  std::vector<std::string> allowed_origins;
};

/// True when a WebSocket upgrade with this Origin header (empty: none sent) to this Host may
/// proceed: no Origin, an Origin whose host:port is the Host, or one of `allowed`.
bool OriginAllowed(std::string_view origin, std::string_view host,
                   const std::vector<std::string>& allowed);

/// Counters of the HTTP port.
struct HttpStats {
  std::atomic<uint64_t> connections_accepted{0};
  std::atomic<uint64_t> connections_refused{0};
  std::atomic<uint64_t> idle_timeouts{0};
  std::atomic<uint64_t> websocket_upgrades{0};
  std::atomic<uint64_t> tls_handshake_failures{0};
  std::mutex responses_mu;
  std::map<int, uint64_t> responses;  // by status code
};

/// The HTTP front. Thread safety: Start/Stop from the owning thread; the rest from any thread.
class HttpServer {
 public:
  HttpServer(asio::io_context& io, HttpConfig config, Server& server);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Binds and listens on config.listen, over TLS (HTTPS, WSS) when the Server has a TLS
  /// configuration (its Start must have run). Returns the bound port; InvalidArgument for a bad
  /// address or a non-loopback address without TLS or tls.allow_plaintext, Unavailable when it
  /// cannot listen.
  StatusOr<uint16_t> Start();
  /// Closes the acceptor and the HTTP connections (WebSocket sessions close with the Server).
  void Stop();

  /// The /metrics page: sessions, strokes, latencies, bytes, replication, meshes, HTTP, then
  /// what each added source writes.
  std::string MetricsText();
  /// Adds a writer of more families (the edit log's fsync time, the compute queue depth, ...),
  /// called on every scrape from an I/O thread; it must only read atomics or take short locks.
  void AddMetricsSource(std::function<void(MetricsWriter&)> source);
  /// Ok when every hosted scene is recovered and its edit log directory is writable with space
  /// left; Unavailable naming the first that is not.
  Status Readiness();

  const HttpConfig& config() const { return config_; }
  HttpStats& stats() { return *stats_; }
  size_t open_connections() const { return static_cast<size_t>(open_->load()); }

 private:
  class Connection;
  template <class Stream>
  class BasicConnection;
  void Accept();
  void CountResponse(int code);

  asio::io_context& io_;
  HttpConfig config_;
  Server& server_;
  StaticFiles files_;
  tcp::acceptor acceptor_;
  AcceptPause accept_pause_;
  std::string csp_;  // Content-Security-Policy of every response (with the allowed origins)
  std::shared_ptr<boost::asio::ssl::context> tls_;  // null: plain HTTP
  std::atomic<bool> stopped_{false};
  // Shared with the connection slots, which may outlive this object in queued handlers.
  std::shared_ptr<std::atomic<int64_t>> open_ = std::make_shared<std::atomic<int64_t>>(0);
  std::shared_ptr<HttpStats> stats_ = std::make_shared<HttpStats>();
  std::mutex sources_mu_;
  std::vector<std::function<void(MetricsWriter&)>> sources_;
  std::mutex connections_mu_;
  std::map<uint64_t, std::weak_ptr<Connection>> connections_;
  uint64_t next_connection_ = 1;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_HTTP_SERVER_H_
