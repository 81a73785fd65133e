/// @brief AcceptPause: what an accept loop does after a failed accept (out of file descriptors,
/// of kernel memory): pause, growing, instead of spinning, and say so once per interval.
#ifndef SCULPT_SERVER_NET_ACCEPT_PAUSE_H_
#define SCULPT_SERVER_NET_ACCEPT_PAUSE_H_

#include <chrono>
#include <functional>
#include <string>

#include "net/log_limiter.h"
#include "net/net.h"

namespace sculpt::server {

/// Out of descriptors (EMFILE, ENFILE), the connection stays in the backlog and the acceptor is
/// readable again at once: accepting again at once spins a core and writes the same log line
/// without end. After a failure the loop pauses 10 ms, doubling up to 1 s while failures go on,
/// and the condition is logged at most once per 10 s with the number of failures.
/// Thread safety: the accept loop's handlers (one at a time) call it.
class AcceptPause {
 public:
  /// `what` names the acceptor in the log ("accept on 127.0.0.1:7420").
  AcceptPause(asio::io_context& io, std::string what);

  /// Counts the failure, logs it if its interval allows, and calls `resume` after the pause
  /// (not at all if Cancel comes first).
  void OnError(const boost::system::error_code& ec, std::function<void()> resume);
  /// An accept succeeded: the next failure pauses 10 ms again.
  void Succeeded() { pause_ = std::chrono::milliseconds(0); }
  void Cancel() { timer_.cancel(); }
  std::chrono::milliseconds pause() const { return pause_; }

 private:
  asio::steady_timer timer_;
  std::string what_;
  std::chrono::milliseconds pause_{0};
  LogLimiter log_{std::chrono::seconds(10)};
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_ACCEPT_PAUSE_H_
