/// @brief AckGate: acknowledgements released in sequence order once durable where they must be.
#include "scene/ack_gate.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

namespace sculpt::server {

AckGate::AckGate(Options options) : options_(std::move(options)) {
  // With an injected clock the test drives CheckFallback itself.
  if (options_.sync && options_.fallback.count() > 0 && !options_.now) {
    timer_ = std::thread([this] { TimerLoop(); });
  }
}

AckGate::~AckGate() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  timer_cv_.notify_all();
  if (timer_.joinable()) timer_.join();
}

AckGate::Clock::time_point AckGate::Now() const {
  return options_.now ? options_.now() : Clock::now();
}

uint64_t AckGate::StandbyBoundLocked() const {
  uint64_t bound = standby_durable_;
  for (auto it = skipped_.begin(); it != skipped_.end() && it->first <= bound + 1; ++it) {
    bound = std::max(bound, it->second);
  }
  return bound;
}

uint64_t AckGate::BoundLocked() const {
  if (!options_.sync || fallen_back_.load()) return local_durable_;
  return std::min(local_durable_, StandbyBoundLocked());
}

void AckGate::Skip(uint64_t first, uint64_t last) {
  if (!options_.sync || last < first) return;
  std::lock_guard<std::mutex> lock(mu_);
  if (last <= standby_durable_) return;
  uint64_t& end = skipped_[first];
  end = std::max(end, last);
}

void AckGate::Hold(uint64_t seq, std::function<void()> answer) {
  bool first = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    first = held_.empty();
    held_.push_back({seq, Now(), std::move(answer)});
    newest_held_ = std::max(newest_held_, seq);
  }
  // The timer sleeps while nothing is held: a new front has a deadline to wait for.
  if (first && timer_.joinable()) timer_cv_.notify_all();
  Release();
}

void AckGate::LocalDurable(uint64_t seq) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    local_durable_ = std::max(local_durable_, seq);
  }
  Release();
}

void AckGate::StandbyDurable(uint64_t seq) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    standby_durable_ = std::max(standby_durable_, seq);
    while (!skipped_.empty() && skipped_.begin()->second <= standby_durable_) {
      skipped_.erase(skipped_.begin());
    }
    if (fallen_back_ && StandbyBoundLocked() >= resume_at_) {
      fallen_back_ = false;
      spdlog::info(
          "replication: the standby's copy is durable to seq {} again: acknowledgements wait "
          "for it (sync) from here on",
          standby_durable_);
    }
  }
  Release();
}

size_t AckGate::held() const {
  std::lock_guard<std::mutex> lock(mu_);
  return held_.size();
}

uint64_t AckGate::standby_durable_seq() const {
  std::lock_guard<std::mutex> lock(mu_);
  return standby_durable_;
}

// Called from every thread that moves a bound; the answers must run in sequence order, so one
// caller at a time answers, outside the lock, and picks up what a concurrent caller released
// meanwhile.
void AckGate::Release() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (releasing_) return;
    releasing_ = true;
  }
  for (;;) {
    std::vector<Held> ready;
    {
      std::lock_guard<std::mutex> lock(mu_);
      const uint64_t bound = BoundLocked();
      while (!held_.empty() && held_.front().seq <= bound) {
        ready.push_back(std::move(held_.front()));
        held_.pop_front();
      }
      if (ready.empty()) {
        releasing_ = false;
        return;
      }
    }
    for (Held& h : ready) h.answer();
  }
}

void AckGate::CheckFallback() {
  if (!options_.sync || options_.fallback.count() <= 0) return;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (fallen_back_ || held_.empty()) return;
    const Held& front = held_.front();
    // Only an answer the standby alone holds back counts: a slow local disk is not the
    // standby's fault, and async would not answer it earlier.
    if (Now() - front.since < options_.fallback || front.seq > local_durable_ ||
        front.seq <= StandbyBoundLocked()) {
      return;
    }
    fallen_back_ = true;
    resume_at_ = newest_held_;
    fallbacks_.fetch_add(1);
    spdlog::warn(
        "replication: the standby has not confirmed seq {} within sync_fallback_ms={} (its copy "
        "is durable to seq {}): acknowledging asynchronously until it holds seq {}",
        front.seq, options_.fallback.count(), standby_durable_, resume_at_);
  }
  Release();
}

void AckGate::TimerLoop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_) {
    if (held_.empty() || fallen_back_) {
      // Nothing to time: woken by the next Hold (or every fallback period while fallen back).
      timer_cv_.wait_for(lock, options_.fallback);
      continue;
    }
    const Clock::time_point deadline = held_.front().since + options_.fallback;
    if (Clock::now() < deadline) {
      timer_cv_.wait_until(lock, deadline);
      continue;
    }
    lock.unlock();
    CheckFallback();
    lock.lock();
    // Not fallen back (the front waits for the local log, or was just released): look again
    // shortly rather than spin.
    if (!stop_ && !fallen_back_) timer_cv_.wait_for(lock, std::chrono::milliseconds(5));
  }
}

}  // namespace sculpt::server
