/// @brief RateLimiter: the token bucket that bounds how fast one session may send strokes, poses
/// and the other rate-limited messages.
#ifndef SCULPT_SERVER_NET_RATE_LIMITER_H_
#define SCULPT_SERVER_NET_RATE_LIMITER_H_

#include <chrono>
#include <string>

namespace sculpt::server {

/// A token bucket: `rate` tokens a second flow in, at most `burst` are held, and a message costs
/// one or more tokens. It starts full. Time is passed in so tests need no sleeps.
/// Thread safety: none; one session's strand owns it.
class RateLimiter {
 public:
  using Clock = std::chrono::steady_clock;

  /// A rate or burst that is not finite or is negative is taken as 0 (nothing passes).
  RateLimiter(double rate_per_second, double burst, Clock::time_point now = Clock::now());

  /// Refills up to `now`, then takes `cost` tokens if that many are held. False (nothing taken)
  /// when fewer are held, or when `cost` is negative or not finite.
  bool TryTake(double cost, Clock::time_point now);
  /// Tokens held at `now` (refilled, nothing taken).
  double Available(Clock::time_point now) const;

  double rate() const { return rate_; }
  double burst() const { return burst_; }
  /// The allowed range as an Error names it: "[0, 240] (burst 60)".
  std::string AllowedRange() const;

 private:
  double Refilled(Clock::time_point now) const;

  double rate_;
  double burst_;
  double tokens_;
  Clock::time_point last_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_RATE_LIMITER_H_
