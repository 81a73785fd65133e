/// @brief BudgetPool: the rate limits a source address or a named user shares across all its
/// sessions, so that opening more connections, or reconnecting, buys no more than one budget.
#ifndef SCULPT_SERVER_NET_BUDGET_POOL_H_
#define SCULPT_SERVER_NET_BUDGET_POOL_H_

#include <chrono>
#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "config/server_config.h"
#include "net/rate_limiter.h"

namespace sculpt::server {

/// The three token buckets of one key, `factor` clients' worth of the per-client limits.
/// Thread safety: every method locks; any session's strand may call it.
class SharedBudget {
 public:
  using Clock = RateLimiter::Clock;
  enum class Kind { kStrokes, kPoses, kRequests };

  SharedBudget(const LimitsConfig& limits, double factor, Clock::time_point now);

  /// Takes `cost` tokens of `kind` if held; false (nothing taken) otherwise, as
  /// RateLimiter::TryTake.
  bool TryTake(Kind kind, double cost, Clock::time_point now);
  /// "[0, 960] (burst 240)" for `kind`.
  std::string AllowedRange(Kind kind) const;
  /// True when every bucket is full at `now`: the budget is then the same as a new one.
  bool Full(Clock::time_point now) const;

 private:
  RateLimiter& Bucket(Kind kind);
  const RateLimiter& Bucket(Kind kind) const;

  mutable std::mutex mu_;
  RateLimiter strokes_;
  RateLimiter poses_;
  RateLimiter requests_;
};

/// Budgets by key ("addr:10.0.0.7", "user:alice"). A budget lives while a session holds it and,
/// after that, until it has refilled (a key that reconnects finds its drained budget again);
/// full, unheld budgets are dropped when the pool has grown. Thread safety: any thread.
class BudgetPool {
 public:
  explicit BudgetPool(const LimitsConfig& limits) : limits_(limits) {}

  /// The budget of `key`, made with `factor` clients' worth of the limits if new.
  std::shared_ptr<SharedBudget> Get(const std::string& key, double factor,
                                    SharedBudget::Clock::time_point now = SharedBudget::Clock::now());
  size_t size() const;

 private:
  const LimitsConfig limits_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, std::shared_ptr<SharedBudget>> budgets_;
  size_t prune_at_ = 256;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_BUDGET_POOL_H_
