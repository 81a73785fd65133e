/// @brief BudgetPool: rate limits shared by the sessions of one source address or user.
#include "net/budget_pool.h"

#include <algorithm>

namespace sculpt::server {

SharedBudget::SharedBudget(const LimitsConfig& l, double f, Clock::time_point now)
    : strokes_(l.strokes_per_second * f, l.stroke_burst * f, now),
      poses_(l.poses_per_second * f, l.pose_burst * f, now),
      requests_(l.requests_per_second * f, l.request_burst * f, now) {}

RateLimiter& SharedBudget::Bucket(Kind kind) {
  return kind == Kind::kStrokes ? strokes_ : kind == Kind::kPoses ? poses_ : requests_;
}

const RateLimiter& SharedBudget::Bucket(Kind kind) const {
  return kind == Kind::kStrokes ? strokes_ : kind == Kind::kPoses ? poses_ : requests_;
}

bool SharedBudget::TryTake(Kind kind, double cost, Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mu_);
  return Bucket(kind).TryTake(cost, now);
}

std::string SharedBudget::AllowedRange(Kind kind) const {
  std::lock_guard<std::mutex> lock(mu_);
  return Bucket(kind).AllowedRange();
}

bool SharedBudget::Full(Clock::time_point now) const {
  std::lock_guard<std::mutex> lock(mu_);
  for (const RateLimiter* b : {&strokes_, &poses_, &requests_}) {
    if (b->Available(now) < b->burst()) return false;
  }
  return true;
}

std::shared_ptr<SharedBudget> BudgetPool::Get(const std::string& key, double factor,
                                              SharedBudget::Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mu_);
  if (auto it = budgets_.find(key); it != budgets_.end()) return it->second;
  if (budgets_.size() >= prune_at_) {
    // Held by nobody and refilled: indistinguishable from a budget made afresh.
    for (auto it = budgets_.begin(); it != budgets_.end();) {
      if (it->second.use_count() == 1 && it->second->Full(now)) {
        it = budgets_.erase(it);
      } else {
        ++it;
      }
    }
    prune_at_ = std::max<size_t>(256, 2 * budgets_.size());
  }
  auto b = std::make_shared<SharedBudget>(limits_, factor, now);
  budgets_.emplace(key, b);
  return b;
}

size_t BudgetPool::size() const {
  std::lock_guard<std::mutex> lock(mu_);
  return budgets_.size();
}

}  // namespace sculpt::server
