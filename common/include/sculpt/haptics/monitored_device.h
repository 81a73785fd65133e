/// @brief MonitoredDevice: a HapticDevice decorator that records what the loop rendered (force
/// statistics, ticks per snapshot version, an optional per-tick trace) for reports and tests.
#ifndef SCULPT_HAPTICS_MONITORED_DEVICE_H_
#define SCULPT_HAPTICS_MONITORED_DEVICE_H_

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "sculpt/haptics/haptic_device.h"
#include "sculpt/haptics/haptic_loop.h"

namespace sculpt::haptics {

/// Forwards Read and ApplyForce to `inner` and keeps: the largest force and the mean force over
/// ticks with a non-zero force (contact), the ticks spent on each snapshot version (the version
/// current at Read: the tick's own, or a newer one the loop has not taken yet), and up to
/// `trace_capacity` ticks of (t, position, force, version).
/// Thread safety: Read/ApplyForce on the loop's thread; the accessors only once the loop has
/// stopped.
class MonitoredDevice : public HapticDevice {
 public:
  struct Tick {
    double t = 0;
    Vec3 position;
    Vec3 force;
    uint64_t version = 0;
  };
  struct ForceStats {
    uint64_t ticks = 0;
    uint64_t contact_ticks = 0;   // ticks with a non-zero force
    double first_contact_s = -1;  // loop time of the first, -1 if none
    double max_force = 0;
    double mean_contact_force = 0;
    Vec3 last_force;
  };

  /// `inner` and `publisher` must outlive this device. The trace is reserved up front, so the
  /// loop never allocates for it.
  MonitoredDevice(HapticDevice* inner, const SnapshotPublisher* publisher,
                  size_t trace_capacity = 0);

  DeviceSample Read(double t) override;
  void ApplyForce(const Vec3& force, double t) override;

  ForceStats force_stats() const;
  const std::vector<Tick>& trace() const { return trace_; }
  /// Ticks spent on any of `versions`.
  uint64_t TicksOn(const std::vector<uint64_t>& versions) const;

 private:
  HapticDevice* inner_;
  const SnapshotPublisher* publisher_;
  size_t trace_capacity_;
  std::vector<Tick> trace_;
  std::unordered_map<uint64_t, uint64_t> ticks_by_version_;
  DeviceSample last_sample_;
  uint64_t last_version_ = 0;
  ForceStats stats_;
  double contact_force_sum_ = 0;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_MONITORED_DEVICE_H_
