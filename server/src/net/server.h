/// @brief The TCP front of sculptd: accepts connections, runs one session per client (on its
/// own strand), authenticates, validates every message and hands strokes to the scene actor.
#ifndef SCULPT_SERVER_NET_SERVER_H_
#define SCULPT_SERVER_NET_SERVER_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "config/server_config.h"
#include "net/net.h"
#include "scene/scene.h"

namespace sculpt::server {

class Session;

/// Metrics a test or an operator reads.
struct ServerStats {
  std::atomic<uint64_t> connections{0};
  std::atomic<uint64_t> strokes_accepted{0};
  std::atomic<uint64_t> strokes_refused{0};
  std::atomic<uint64_t> errors_sent{0};
  std::atomic<uint64_t> disconnects_for_cause{0};
};

/// Owns the acceptor and the set of live sessions. Thread safety: Start/Stop from the owning
/// thread; sessions call back on their strands.
class Server {
 public:
  Server(asio::io_context& io, const ServerConfig& config, Scene& scene);
  ~Server();

  /// Binds and listens on config.listen. Returns the bound port (useful with port 0).
  StatusOr<uint16_t> Start();
  /// Closes the acceptor and every session with a Bye.
  void Stop();

  const ServerConfig& config() const { return config_; }
  Scene& scene() { return scene_; }
  ServerStats& stats() { return stats_; }
  asio::io_context& io() { return io_; }

  // Called by sessions.
  bool Register(const std::shared_ptr<Session>& s);
  void Unregister(const Session* s);
  void BroadcastPresence();

 private:
  void Accept();
  void SchedulePresence();

  asio::io_context& io_;
  ServerConfig config_;
  Scene& scene_;
  tcp::acceptor acceptor_;
  asio::steady_timer presence_timer_;
  std::mutex sessions_mu_;
  std::set<std::shared_ptr<Session>> sessions_;
  std::atomic<uint64_t> next_session_id_{1};
  std::atomic<bool> stopped_{false};
  ServerStats stats_;

  friend class Session;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_SERVER_H_
