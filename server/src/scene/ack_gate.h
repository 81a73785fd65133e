/// @brief AckGate: holds a scene's acknowledgements until what they need is durable (the owner's
/// log, and with synchronous replication the standby's copy too) and answers them in sequence
/// order.
#ifndef SCULPT_SERVER_SCENE_ACK_GATE_H_
#define SCULPT_SERVER_SCENE_ACK_GATE_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

namespace sculpt::server {

/// The acknowledgements of one scene, each waiting for its sequence to be durable.
///
/// Asynchronous (the default): an answer at seq S runs once the local log is durable to S.
/// Synchronous (`sync`): once the local log *and* the standby's copy (StandbyDurable) are durable
/// to S. A standby that does not confirm an answer's seq within `fallback` (none connected, or
/// stuck) switches the gate to async ("fallen back"), counted and logged, until the standby
/// confirms every seq held when it fell back; then it is synchronous again. `fallback` zero: the
/// gate never falls back (answers wait for the standby however long it takes).
/// Answers run in sequence order, one caller at a time, outside the lock (a client's acks are in
/// the order of its strokes; see commit 1219ad8).
/// Thread safety: every method from any thread; answers run on the thread whose call released
/// them (the compute thread, the log's sync thread, a session strand, or the gate's own timer
/// thread when it falls back), so they must only post work elsewhere.
class AckGate {
 public:
  using Clock = std::chrono::steady_clock;
  struct Options {
    bool sync = false;
    std::chrono::milliseconds fallback{1000};
    /// Tests: the clock the fallback is measured with.
    std::function<Clock::time_point()> now;
  };

  explicit AckGate(Options options);
  /// Stops the timer thread; answers still held are dropped unanswered (the scene answers its
  /// requesters' sessions by closing them at shutdown).
  ~AckGate();
  AckGate(const AckGate&) = delete;
  AckGate& operator=(const AckGate&) = delete;

  /// Queues `answer` for seq (seqs must not decrease from one call to the next) and answers
  /// whatever is releasable now.
  void Hold(uint64_t seq, std::function<void()> answer);
  /// The local log is durable up to `seq` (values below an earlier one are ignored).
  void LocalDurable(uint64_t seq);
  /// The standby's copy is durable up to `seq` (values below an earlier one are ignored).
  void StandbyDurable(uint64_t seq);
  /// Seqs first..last will never reach the standby's copy (no standby was subscribed when the
  /// edit was sent; a subscribed one gets every record, ReplicationHub::ShipRecords). An answer
  /// waits for the standby only up to the seq before them; without this it waited for the next
  /// edit the standby does get, or the fall-back. Call before the Hold of an answer at `last`.
  void Skip(uint64_t first, uint64_t last);
  /// Tests with an injected clock: checks the fallback deadline now (the timer thread does it by
  /// itself at the deadline on the real clock).
  void CheckFallback();

  bool sync() const { return options_.sync; }
  size_t held() const;
  uint64_t standby_durable_seq() const;
  /// Synchronous, but fallen back to async for now.
  bool fallen_back() const { return fallen_back_.load(); }
  /// Times the gate fell back since start.
  uint64_t fallbacks() const { return fallbacks_.load(); }

 private:
  struct Held {
    uint64_t seq;
    Clock::time_point since;
    std::function<void()> answer;
  };
  Clock::time_point Now() const;
  // The seq up to which answers may go; caller holds mu_.
  uint64_t BoundLocked() const;
  // standby_durable_ carried across the skipped seqs that follow it; caller holds mu_.
  uint64_t StandbyBoundLocked() const;
  void Release();
  void TimerLoop();

  const Options options_;
  mutable std::mutex mu_;
  std::condition_variable timer_cv_;
  std::deque<Held> held_;         // guarded by mu_, in seq order
  uint64_t local_durable_ = 0;    // guarded by mu_
  uint64_t standby_durable_ = 0;  // guarded by mu_
  std::map<uint64_t, uint64_t> skipped_;  // guarded by mu_: first -> last, above standby_durable_
  uint64_t newest_held_ = 0;      // guarded by mu_: the highest seq ever held
  uint64_t resume_at_ = 0;        // guarded by mu_: fallen back until the standby reaches it
  bool releasing_ = false;        // guarded by mu_: one thread answers at a time
  bool stop_ = false;             // guarded by mu_
  std::atomic<bool> fallen_back_{false};
  std::atomic<uint64_t> fallbacks_{0};
  std::thread timer_;  // sync with a fallback only
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_ACK_GATE_H_
