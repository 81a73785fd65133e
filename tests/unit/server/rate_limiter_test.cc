#include "net/rate_limiter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace sculpt::server {
namespace {

using Clock = RateLimiter::Clock;
using std::chrono::milliseconds;

TEST(RateLimiterTest, StartsFullAndRefusesPastTheBurst) {
  const Clock::time_point t0{};
  RateLimiter r(10, 3, t0);
  EXPECT_TRUE(r.TryTake(1, t0));
  EXPECT_TRUE(r.TryTake(1, t0));
  EXPECT_TRUE(r.TryTake(1, t0));
  EXPECT_FALSE(r.TryTake(1, t0));
}

TEST(RateLimiterTest, RefillsAtTheRateUpToTheBurst) {
  const Clock::time_point t0{};
  RateLimiter r(10, 3, t0);
  EXPECT_TRUE(r.TryTake(3, t0));
  EXPECT_FALSE(r.TryTake(1, t0 + milliseconds(50)));   // 0.5 tokens
  EXPECT_TRUE(r.TryTake(1, t0 + milliseconds(100)));   // 1.0
  EXPECT_NEAR(r.Available(t0 + milliseconds(10'100)), 3.0, 1e-9);  // capped at the burst
}

TEST(RateLimiterTest, ARefusedTakeTakesNothing) {
  const Clock::time_point t0{};
  RateLimiter r(0, 5, t0);
  EXPECT_FALSE(r.TryTake(6, t0));
  EXPECT_TRUE(r.TryTake(5, t0));
}

TEST(RateLimiterTest, RejectsNegativeAndNanCosts) {
  const Clock::time_point t0{};
  RateLimiter r(10, 5, t0);
  EXPECT_FALSE(r.TryTake(-1, t0));
  EXPECT_FALSE(r.TryTake(std::numeric_limits<double>::quiet_NaN(), t0));
  EXPECT_NEAR(r.Available(t0), 5.0, 1e-12);
}

TEST(RateLimiterTest, ATimeBeforeTheLastDoesNotDrainOrRefill) {
  const Clock::time_point t0 = Clock::time_point{} + milliseconds(1000);
  RateLimiter r(10, 2, t0);
  EXPECT_TRUE(r.TryTake(2, t0));
  EXPECT_FALSE(r.TryTake(1, t0 - milliseconds(500)));
  EXPECT_TRUE(r.TryTake(1, t0 + milliseconds(100)));
}

TEST(RateLimiterTest, NamesItsRange) {
  RateLimiter r(240, 60);
  EXPECT_EQ(r.AllowedRange(), "[0, 240] (burst 60)");
}

}  // namespace
}  // namespace sculpt::server
