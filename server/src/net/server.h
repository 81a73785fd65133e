/// @brief The front of sculptd: the TCP acceptor, the set of live sessions (TCP and WebSocket
/// alike), presence broadcasts and the counters /metrics reports.
#ifndef SCULPT_SERVER_NET_SERVER_H_
#define SCULPT_SERVER_NET_SERVER_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "config/server_config.h"
#include "net/accept_pause.h"
#include "net/budget_pool.h"
#include "net/log_limiter.h"
#include "net/metrics.h"
#include "net/net.h"
#include "net/transport.h"
#include "net/users.h"
#include "scene/scene.h"

namespace sculpt::v1 {
class Error;
}  // namespace sculpt::v1

namespace boost::asio::ssl {
class context;
}  // namespace boost::asio::ssl

namespace sculpt::server::cluster {
class SceneRouter;
}  // namespace sculpt::server::cluster

namespace sculpt::server {

class Session;

/// Metrics a test or an operator reads. Per-transport arrays are indexed by TransportKind.
struct ServerStats {
  std::atomic<uint64_t> connections{0};
  std::atomic<uint64_t> strokes_accepted{0};
  std::atomic<uint64_t> strokes_refused{0};
  std::atomic<uint64_t> errors_sent{0};
  std::atomic<uint64_t> disconnects_for_cause{0};
  /// Mesh chunk frames replaced, unsent, by a newer version of the same chunk.
  std::atomic<uint64_t> frames_superseded{0};
  /// TLS handshakes that failed or timed out (plaintext on a TLS port, bad certificates).
  std::atomic<uint64_t> tls_handshake_failures{0};
  /// Connections refused at once: limits.max_sessions, max_connections_per_source, or the
  /// source's request budget (connections per second).
  std::atomic<uint64_t> connections_refused{0};
  /// Sessions closed by a timeout after authentication: join, idle, an incomplete frame.
  std::atomic<uint64_t> sessions_timed_out{0};
  /// Failed accepts (EMFILE, ENFILE, ...), each followed by a growing pause of the acceptor.
  std::atomic<uint64_t> accept_errors{0};
  std::array<std::atomic<uint64_t>, kTransportKinds> bytes_in{};
  std::array<std::atomic<uint64_t>, kTransportKinds> bytes_out{};
  std::array<std::atomic<uint64_t>, kTransportKinds> messages_in{};
  /// From a stroke's arrival to its Ack leaving the session (durable and applied).
  std::array<LatencyHistogram, kTransportKinds> stroke_ack_seconds;
};

/// Live sessions counted by (role name, transport name), for /metrics.
using SessionCounts = std::map<std::pair<std::string, std::string>, uint64_t>;

/// Owns the TCP acceptor and the set of live sessions of every scene this process hosts.
/// Thread safety: Start/Stop from the owning thread; every other method from any thread.
class Server {
 public:
  /// `scenes`: the hosted scenes (HostedScenes(config) order), non-empty, outliving the server;
  /// the first is the default scene, the one a JoinScene naming no scene joins.
  Server(asio::io_context& io, const ServerConfig& config, std::vector<Scene*> scenes);
  /// A server of one scene (tests, tools): Server(io, config, {&scene}).
  Server(asio::io_context& io, const ServerConfig& config, Scene& scene)
      : Server(io, config, std::vector<Scene*>{&scene}) {}
  ~Server();

  /// Loads the TLS files (config.tls), binds and listens on config.listen. Returns the bound
  /// port (useful with port 0); InvalidArgument naming the key and file of a bad TLS setting.
  StatusOr<uint16_t> Start();
  /// Closes the acceptor and every session with a Bye.
  void Stop();

  const ServerConfig& config() const { return config_; }
  /// The default scene (the first hosted).
  Scene& scene() { return *scenes_.front(); }
  /// The hosted scene named `name`; null when this process does not host it.
  Scene* FindScene(const std::string& name);
  /// Every hosted scene, the default first.
  const std::vector<Scene*>& scenes() const { return scenes_; }
  ServerStats& stats() { return stats_; }
  asio::io_context& io() { return io_; }
  /// Who may connect (valid after Start).
  Authenticator& auth() { return *auth_; }
  /// Re-reads the users file (SIGHUP); the previous users stay in force on error.
  Status ReloadUsers();
  /// The HTTP port's TLS context (no client certificates asked), null when TLS is off. Set by
  /// Start.
  std::shared_ptr<boost::asio::ssl::context> http_tls_context() const { return http_tls_; }

  /// Cluster mode (issue 17): where a JoinScene is served (cluster/scene_router.h); null (the
  /// default): this process serves its scene alone. Set before Start; outlives the server.
  void set_router(const cluster::SceneRouter* router) { router_ = router; }
  const cluster::SceneRouter* router() const { return router_; }

  /// Runs a session on a connection another front accepted (the HTTP server's WebSocket
  /// upgrades). False, and the transport closed, after Stop.
  bool Adopt(Strand strand, std::shared_ptr<Transport> transport);

  // Called by sessions.
  void Unregister(const Session* s);
  /// Sends each scene's joined sessions the presence of that scene's sessions only.
  void BroadcastPresence();
  /// Sessions that have joined, and how many of them are viewers.
  struct Seats {
    size_t joined = 0;
    size_t viewers = 0;
  };
  /// The seats taken in `scene` (limits.max_clients_per_scene counts them).
  Seats JoinedSeats(const Scene& scene);
  /// The seats taken in every hosted scene together (a cluster member's load).
  Seats JoinedSeats();
  /// The rate limits shared by the sessions of one source address or one named user.
  BudgetPool& budgets() { return budgets_; }
  /// Live sessions from `source` (an address without port).
  uint32_t SessionsFrom(const std::string& source);
  SessionCounts CountSessions();

 private:
  enum class Admission { kAdmitted, kRefused, kStopped };

  void Accept();
  void SchedulePresence();
  // Admits `s` under the session caps and its source's connection budget, or says why not.
  Admission Register(const std::shared_ptr<Session>& s, v1::Error* refusal);

  asio::io_context& io_;
  ServerConfig config_;
  const std::vector<Scene*> scenes_;
  tcp::acceptor acceptor_;
  std::shared_ptr<boost::asio::ssl::context> tls_;       // the TCP port's; null: plaintext
  std::shared_ptr<boost::asio::ssl::context> http_tls_;  // the HTTP port's
  asio::steady_timer presence_timer_;
  AcceptPause accept_pause_;
  LogLimiter refusal_log_{std::chrono::seconds(10)};
  BudgetPool budgets_;
  std::mutex sessions_mu_;
  std::set<std::shared_ptr<Session>> sessions_;
  std::unordered_map<std::string, uint32_t> sessions_per_source_;  // under sessions_mu_
  std::atomic<uint64_t> next_session_id_{1};
  std::atomic<bool> stopped_{false};
  ServerStats stats_;
  std::unique_ptr<Authenticator> auth_;
  const cluster::SceneRouter* router_ = nullptr;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_SERVER_H_
