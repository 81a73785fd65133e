#include "net/budget_pool.h"

#include <gtest/gtest.h>

namespace sculpt::server {
namespace {

using Clock = SharedBudget::Clock;
using Kind = SharedBudget::Kind;

LimitsConfig Limits() {
  LimitsConfig l;
  l.strokes_per_second = 10;
  l.stroke_burst = 10;
  l.requests_per_second = 5;
  l.request_burst = 20;
  return l;
}

TEST(BudgetPoolTest, OneKeySharesOneBudgetAcrossItsSessions) {
  BudgetPool pool(Limits());
  const Clock::time_point t0 = Clock::now();
  auto a = pool.Get("addr:10.0.0.7", 1.0, t0);
  auto b = pool.Get("addr:10.0.0.7", 1.0, t0);
  EXPECT_EQ(a.get(), b.get());
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(a->TryTake(Kind::kStrokes, 1, t0));
  EXPECT_FALSE(b->TryTake(Kind::kStrokes, 1, t0));
  EXPECT_TRUE(pool.Get("addr:10.0.0.8", 1.0, t0)->TryTake(Kind::kStrokes, 1, t0));
}

TEST(BudgetPoolTest, FactorScalesRateAndBurst) {
  BudgetPool pool(Limits());
  const Clock::time_point t0 = Clock::now();
  auto a = pool.Get("addr:x", 4.0, t0);
  EXPECT_EQ(a->AllowedRange(Kind::kStrokes), "[0, 40] (burst 40)");
  EXPECT_EQ(a->AllowedRange(Kind::kRequests), "[0, 20] (burst 80)");
}

// A reconnect (the last session released, a new one made) finds the drained budget again.
TEST(BudgetPoolTest, ADrainedBudgetOutlivesItsSessions) {
  BudgetPool pool(Limits());
  const Clock::time_point t0 = Clock::now();
  {
    auto a = pool.Get("user:mallory", 1.0, t0);
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(a->TryTake(Kind::kStrokes, 1, t0));
  }
  // Enough other keys to trigger a prune: the drained one is kept.
  for (int i = 0; i < 600; ++i) pool.Get("addr:" + std::to_string(i), 1.0, t0);
  auto again = pool.Get("user:mallory", 1.0, t0);
  EXPECT_FALSE(again->TryTake(Kind::kStrokes, 1, t0));
  EXPECT_TRUE(again->TryTake(Kind::kStrokes, 1, t0 + std::chrono::milliseconds(150)));
}

TEST(BudgetPoolTest, FullUnheldBudgetsArePruned) {
  BudgetPool pool(Limits());
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < 1000; ++i) pool.Get("addr:" + std::to_string(i), 1.0, t0);
  EXPECT_LT(pool.size(), 300u);
}

}  // namespace
}  // namespace sculpt::server
