/// @brief HapticLoop: the 1 kHz force loop on its own thread, reading immutable snapshots that a
/// SnapshotPublisher swaps in atomically, with its own timing statistics.
#ifndef SCULPT_HAPTICS_HAPTIC_LOOP_H_
#define SCULPT_HAPTICS_HAPTIC_LOOP_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/haptics/haptic_device.h"
#include "sculpt/haptics/haptic_renderer.h"
#include "sculpt/haptics/haptic_settings.h"
#include "sculpt/haptics/penalty.h"

namespace sculpt::haptics {

/// One published field: immutable, with the version and time it was published at.
struct Snapshot {
  std::shared_ptr<const SdfSampler> sdf;  // null: nothing to touch
  uint64_t version = 0;
  std::chrono::steady_clock::time_point published;
};

/// Hands snapshots from whoever builds them (the replica, a test) to the haptic loop. The loop
/// never waits for a publisher: it takes a new snapshot with TryUpdate, which gives up for this
/// tick when a publisher is in the middle of Publish. (std::atomic<std::shared_ptr> is not that:
/// libstdc++ 12 guards it with a spin lock, so a SCHED_FIFO loop whose load meets a store by a
/// preempted SCHED_OTHER publisher spins until the publisher runs again: for its time slice on
/// another CPU, or on the same CPU until the kernel's real-time throttling lets it.) The
/// publisher keeps the last kRetained snapshots alive, so the loop dropping a snapshot is almost
/// never the last reference: a large grid is freed on the publisher's thread (after it lets go
/// of the mutex), not in the middle of a tick.
/// Thread safety: Publish and Current from any thread (they take a mutex); latest_version from
/// any thread, lock-free; TryUpdate from one thread at a time (the loop's), never blocking.
class SnapshotPublisher {
 public:
  static constexpr size_t kRetained = 3;

  SnapshotPublisher();
  /// Publishes `sdf` as the next version (starting at 1).
  void Publish(std::shared_ptr<const SdfSampler> sdf);
  /// The latest snapshot (version 0 with a null sdf before the first Publish). Waits for a
  /// publisher in the middle of Publish: not for the loop's ticks (TryUpdate).
  std::shared_ptr<const Snapshot> Current() const;
  /// The latest version published (0 before the first). Lock-free.
  uint64_t latest_version() const { return latest_version_.load(std::memory_order_acquire); }
  /// If a version other than `*held`'s has been published since and no publisher is inside
  /// Publish at this moment, replaces `*held` (which must not be null) with the latest snapshot
  /// and returns true; otherwise returns false and leaves it. Never waits: a busy publisher
  /// delays the swap by a tick instead of stalling the loop.
  bool TryUpdate(std::shared_ptr<const Snapshot>* held) const;

 private:
  mutable std::mutex publish_mu_;  // orders publishers; the loop only ever try_locks it
  std::atomic<uint64_t> latest_version_{0};
  uint64_t next_version_ = 1;
  std::shared_ptr<const Snapshot> latest_;  // guarded by publish_mu_
  std::deque<std::shared_ptr<const Snapshot>> retained_;
  friend class SnapshotPublisherTestPeer;  // holds the mutex, as a publisher inside Publish
};

/// The loop's timing and event counters. Percentiles come from fixed histograms (tick cost to
/// 0.1 us, period error to 1 us, snapshot lag to 10 us); maxima are exact.
struct HapticLoopStats {
  uint64_t ticks = 0;
  double elapsed_s = 0;
  double rate_hz = 0;  // ticks / elapsed
  double tick_cost_p50_us = 0, tick_cost_p99_us = 0, tick_cost_p999_us = 0, tick_cost_max_us = 0;
  /// |actual period - nominal period| between consecutive tick starts.
  double period_err_p50_us = 0, period_err_p99_us = 0, period_err_max_us = 0;
  uint64_t overruns = 0;          // ticks whose own cost exceeded the period
  uint64_t missed_deadlines = 0;  // tick slots skipped because a tick started a period late
  uint64_t ticks_over_2ms = 0;    // periods between tick starts longer than 2 ms
  uint64_t nan_samples = 0;       // device samples ignored because they were not finite
  uint64_t snapshots_seen = 0;    // distinct snapshot versions the loop switched to
  /// From Publish to the first tick that used the snapshot.
  double snapshot_lag_p50_ms = 0, snapshot_lag_p99_ms = 0, snapshot_lag_max_ms = 0;
  Vec3 last_force;
  bool contact = false;
  /// Ticks the renderer cut short at HapticSettings' budget (TickOutput::over_budget).
  uint64_t ticks_over_budget = 0;
  /// What the loop thread got: "SCHED_FIFO" (with `priority`) or "SCHED_OTHER"; whether
  /// mlockall succeeded; the CPU it is pinned to (-1: not pinned). Empty before Start.
  std::string scheduling;
  int priority = 0;
  bool memory_locked = false;
  int cpu = -1;
};

/// How the loop thread asks the OS for timing. Each request that is refused is logged once per
/// process on stderr and the loop runs as it would without it.
struct HapticLoopOptions {
  /// SCHED_FIFO at `priority` (clamped to the policy's range) through pthread_setschedparam.
  bool realtime = true;
  int priority = 80;
  /// mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) for the process: pages, once touched, are
  /// never paged out under the loop. Attempted only where it cannot fail later allocations
  /// (RLIMIT_MEMLOCK unlimited, or root).
  bool lock_memory = true;
  /// kAutoCpu: the last CPU the process may run on, when it may run on at least 2 (the replica
  /// keeps off it with PinThreadAwayFromCpu); kNoCpu: not pinned; else that CPU.
  static constexpr int kAutoCpu = -2;
  static constexpr int kNoCpu = -1;
  int cpu = kAutoCpu;
};

/// Restricts the calling thread to the CPUs the process may use other than `cpu` (the haptic
/// loop's), so a busy thread such as the replica's replay never competes with the loop for its
/// core. False (and nothing changed) for cpu < 0 or when no other CPU is left.
bool PinThreadAwayFromCpu(int cpu);

/// The haptic loop: a dedicated thread that wakes every 1 / rate_hz seconds (sleep_until on
/// steady_clock, deadlines advanced by the period, not by the wake-up time), loads the current
/// snapshot, reads the device, runs the HapticRenderer and sends the force.
/// Thread safety: Start/Stop from one controlling thread; stats() and SamplePose() from any.
class HapticLoop {
 public:
  /// InvalidArgument for bad settings or a null publisher or device. Both must outlive the loop.
  static StatusOr<std::unique_ptr<HapticLoop>> Create(const HapticSettings& settings,
                                                      SnapshotPublisher* publisher,
                                                      HapticDevice* device,
                                                      const HapticLoopOptions& options = {});
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  /// Starts the thread; FailedPrecondition if it is running.
  Status Start();
  /// Stops and joins the thread (no-op if it is not running).
  void Stop();
  bool running() const;

  HapticLoopStats stats() const;
  /// The CPU the loop thread is (or will be, once started) pinned to; -1 if none.
  int cpu() const;
  /// The stroke sampler hook: the device pose of the latest tick (time in loop seconds), for the
  /// stroke sender to call at stroke rate. Wait-free for the loop, never blocks the caller for
  /// longer than a concurrent pose write.
  DeviceSample SamplePose() const;

 private:
  struct Impl;
  explicit HapticLoop(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_HAPTIC_LOOP_H_
