/// @brief LogLimiter: lets one kind of log line through at most once per interval, counting the
/// ones it held back (a flood of refusals or accept errors writes one line, not millions).
#ifndef SCULPT_SERVER_NET_LOG_LIMITER_H_
#define SCULPT_SERVER_NET_LOG_LIMITER_H_

#include <chrono>
#include <cstdint>
#include <mutex>

namespace sculpt::server {

/// Thread safety: any thread.
class LogLimiter {
 public:
  using Clock = std::chrono::steady_clock;

  explicit LogLimiter(Clock::duration interval) : interval_(interval) {}

  /// 0 when the line is to be held back; otherwise the number of events it reports (this one
  /// and those held back since the last line).
  uint64_t Tick(Clock::time_point now = Clock::now()) {
    std::lock_guard<std::mutex> lock(mu_);
    ++pending_;
    if (logged_once_ && now - last_ < interval_) return 0;
    logged_once_ = true;
    last_ = now;
    const uint64_t n = pending_;
    pending_ = 0;
    return n;
  }

 private:
  const Clock::duration interval_;
  std::mutex mu_;
  bool logged_once_ = false;
  Clock::time_point last_{};
  uint64_t pending_ = 0;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_LOG_LIMITER_H_
