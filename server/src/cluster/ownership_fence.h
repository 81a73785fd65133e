/// @brief OwnershipFence: whether this member may acknowledge edits of its scene right now.
#ifndef SCULPT_SERVER_CLUSTER_OWNERSHIP_FENCE_H_
#define SCULPT_SERVER_CLUSTER_OWNERSHIP_FENCE_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

#include "sculpt/core/status.h"

namespace sculpt::server::cluster {

/// The local half of fencing (issue 17): the scene may be acknowledged only while this member
/// holds its owner key under a lease that etcd confirmed recently enough that it cannot have
/// expired yet. The ClusterAgent grants, extends and revokes; the commit pipeline asks Check()
/// before it sequences an edit and again before it acknowledges one, so a member that loses its
/// lease (keep-alives unanswered past the TTL, etcd saying the lease is gone) stops acknowledging
/// at once, without waiting for any network call.
/// Thread safety: every method from any thread (atomics; a reader may see a grant a moment late,
/// never a validity longer than the one granted).
class OwnershipFence {
 public:
  using Clock = std::chrono::steady_clock;

  explicit OwnershipFence(std::string scene) : scene_(std::move(scene)) {}

  /// Owner at `epoch` until `valid_until`.
  void Grant(uint64_t epoch, Clock::time_point valid_until) {
    valid_until_ns_.store(0, std::memory_order_release);
    epoch_.store(epoch, std::memory_order_release);
    valid_until_ns_.store(Ns(valid_until), std::memory_order_release);
  }
  /// A keep-alive was answered: the ownership (if held) lasts until `valid_until`.
  void Extend(Clock::time_point valid_until) {
    int64_t current = valid_until_ns_.load(std::memory_order_acquire);
    // Never revives a revoked fence (0); a later deadline only.
    while (current != 0 && !valid_until_ns_.compare_exchange_weak(current, Ns(valid_until))) {
    }
  }
  /// Ownership is gone (lease lost, owner key taken): nothing is acknowledged from now on.
  void Revoke() { valid_until_ns_.store(0, std::memory_order_release); }

  /// Ok while owned and before the deadline; otherwise Unavailable naming the scene and the
  /// epoch last held, so the client retries through another member.
  Status Check(Clock::time_point now = Clock::now()) const {
    const int64_t until = valid_until_ns_.load(std::memory_order_acquire);
    if (until != 0 && Ns(now) < until) return Status::Ok();
    const uint64_t epoch = epoch_.load(std::memory_order_acquire);
    return Status(
        Status::Code::kUnavailable,
        "scene " + scene_ + ": this member is not its owner now (" +
            (epoch == 0
                 ? std::string("never acquired")
                 : "ownership of epoch " + std::to_string(epoch) +
                       (until == 0 ? " lost" : " not confirmed by etcd within its lease TTL")) +
            "): nothing is acknowledged here; reconnect through any member");
  }
  bool held(Clock::time_point now = Clock::now()) const { return Check(now).ok(); }
  /// The epoch last granted (0: never).
  uint64_t epoch() const { return epoch_.load(std::memory_order_acquire); }
  const std::string& scene() const { return scene_; }

 private:
  static int64_t Ns(Clock::time_point t) {
    // Never 0 for a real deadline: 0 means revoked.
    const int64_t ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
    return ns == 0 ? 1 : ns;
  }

  const std::string scene_;
  std::atomic<uint64_t> epoch_{0};
  std::atomic<int64_t> valid_until_ns_{0};
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_OWNERSHIP_FENCE_H_
