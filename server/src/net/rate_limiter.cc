/// @brief RateLimiter: a token bucket per session.
#include "net/rate_limiter.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace sculpt::server {
namespace {

double NonNegative(double v) { return std::isfinite(v) && v > 0 ? v : 0.0; }

std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

}  // namespace

RateLimiter::RateLimiter(double rate_per_second, double burst, Clock::time_point now)
    : rate_(NonNegative(rate_per_second)), burst_(NonNegative(burst)), tokens_(burst_), last_(now) {}

double RateLimiter::Refilled(Clock::time_point now) const {
  // A clock that steps back (it should not, being steady) adds nothing rather than draining.
  const double dt = std::max(0.0, std::chrono::duration<double>(now - last_).count());
  return std::min(burst_, tokens_ + rate_ * dt);
}

bool RateLimiter::TryTake(double cost, Clock::time_point now) {
  tokens_ = Refilled(now);
  if (now > last_) last_ = now;
  if (!std::isfinite(cost) || cost < 0 || tokens_ < cost) return false;
  tokens_ -= cost;
  return true;
}

double RateLimiter::Available(Clock::time_point now) const { return Refilled(now); }

std::string RateLimiter::AllowedRange() const {
  return "[0, " + Num(rate_) + "] (burst " + Num(burst_) + ")";
}

}  // namespace sculpt::server
