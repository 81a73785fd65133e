/// @brief SculptureFeed: hands a producer's immutable sculpture copies (the client's replica
/// publishes them) to the haptic loop's SnapshotPublisher without another copy, each sealed by
/// its state hash so a copy changed after publication (a torn state for the loop) is caught.
#ifndef SCULPT_HAPTICS_SCULPTURE_FEED_H_
#define SCULPT_HAPTICS_SCULPTURE_FEED_H_

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "sculpt/haptics/haptic_loop.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::haptics {

class SculptureSnapshot;

/// Wraps each published sculpture in a SculptureSnapshot that shares it and publishes that. With
/// sealing on, the sculpture's StateHash is taken at publication and taken again when the feed
/// lets the copy go (after kHeld newer ones) or at CheckHeld: a difference means somebody edited
/// a copy the loop may have been reading, and its publisher version is recorded. The feed must
/// be its publisher's only producer (it reads the version back after each Publish).
/// Thread safety: Publish, CheckHeld, stats and changed_versions from any thread; they share a
/// mutex the haptic loop never takes (the loop only loads the publisher's atomic pointer).
class SculptureFeed {
 public:
  static constexpr size_t kHeld = SnapshotPublisher::kRetained + 1;

  struct Stats {
    uint64_t published = 0;  // snapshots handed to the publisher
    uint64_t checked = 0;    // seals checked again
    uint64_t changed = 0;    // of those, hashes that differed
    uint64_t last_seq = 0;   // the producer's sequence of the latest snapshot
    uint64_t last_version = 0;
    double seal_ms = 0;  // time spent hashing, on the caller's threads
    uint64_t windows = 0;     // snapshots published with a dense window
    uint64_t recentred = 0;   // of those, republished copies for a tool that left its window
    double window_ms = 0;     // time spent filling windows, on the caller's threads
  };

  /// `publisher` must outlive the feed. `seal` off: no hashing (then `changed` stays 0).
  SculptureFeed(SnapshotPublisher* publisher, bool seal);
  ~SculptureFeed();
  SculptureFeed(const SculptureFeed&) = delete;
  SculptureFeed& operator=(const SculptureFeed&) = delete;

  /// Publishes `sculpture` (taken at the producer's sequence `seq`); a null pointer is ignored.
  void Publish(std::shared_ptr<const levelset::Sculpture> sculpture, uint64_t seq);
  /// From now on each snapshot carries a dense window (SculptureSnapshot) of `radius` world units
  /// around `centre()` (the haptic tool's position; the loop's SamplePose is wait-free), filled
  /// on the publishing thread. A null `centre` stops it.
  void SetWindow(std::function<Vec3()> centre, double radius);
  /// When the tool has moved more than a quarter of the radius from the latest window's centre
  /// and no new copy came meanwhile, publishes the latest copy again with a window around it
  /// (no copy, no hash). Call from a thread other than the loop's, at a few hundred Hz at most.
  /// True if it republished.
  bool RecentreWindow();
  /// Checks the seals of the copies still held and lets them go (call when the loop stops).
  void CheckHeld();
  Stats stats() const;
  /// Publisher versions whose copy changed after publication.
  std::vector<uint64_t> changed_versions() const;

 private:
  struct Held {
    std::shared_ptr<const levelset::Sculpture> sculpture;
    uint64_t version = 0;
    uint64_t hash = 0;
  };
  void CheckLocked(const Held& h);
  void PublishLocked(std::shared_ptr<const levelset::Sculpture> sculpture);

  SnapshotPublisher* publisher_;
  bool seal_;
  mutable std::mutex mu_;
  std::deque<Held> held_;
  Stats stats_;
  std::vector<uint64_t> changed_;
  std::function<Vec3()> window_centre_;
  double window_radius_ = 0;
  Vec3 last_centre_;
  // The last windowed snapshot published: the next one compares its window with it, so the
  // loop's renderer knows how far phi moved around the tool (SdfSampler::ChangeSince).
  std::shared_ptr<const SculptureSnapshot> last_windowed_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_SCULPTURE_FEED_H_
