/// @brief MonitoredDevice: force statistics, ticks per snapshot version and the trace.
#include "sculpt/haptics/monitored_device.h"

#include <algorithm>

namespace sculpt::haptics {

MonitoredDevice::MonitoredDevice(HapticDevice* inner, const SnapshotPublisher* publisher,
                                 size_t trace_capacity)
    : inner_(inner), publisher_(publisher), trace_capacity_(trace_capacity) {
  trace_.reserve(trace_capacity_);
}

DeviceSample MonitoredDevice::Read(double t) {
  last_sample_ = inner_->Read(t);
  last_version_ = publisher_->latest_version();  // lock-free: this runs on the loop's thread
  ++ticks_by_version_[last_version_];
  return last_sample_;
}

void MonitoredDevice::ApplyForce(const Vec3& force, double t) {
  inner_->ApplyForce(force, t);
  const double f = force.Length();
  ++stats_.ticks;
  stats_.last_force = force;
  stats_.max_force = std::max(stats_.max_force, f);
  if (f > 0) {
    if (stats_.contact_ticks == 0) stats_.first_contact_s = t;
    ++stats_.contact_ticks;
    contact_force_sum_ += f;
  }
  if (trace_.size() < trace_capacity_) {
    trace_.push_back(Tick{t, last_sample_.position, force, last_version_});
  }
}

MonitoredDevice::ForceStats MonitoredDevice::force_stats() const {
  ForceStats s = stats_;
  s.mean_contact_force =
      s.contact_ticks ? contact_force_sum_ / static_cast<double>(s.contact_ticks) : 0.0;
  return s;
}

uint64_t MonitoredDevice::TicksOn(const std::vector<uint64_t>& versions) const {
  uint64_t n = 0;
  for (uint64_t v : versions) {
    auto it = ticks_by_version_.find(v);
    if (it != ticks_by_version_.end()) n += it->second;
  }
  return n;
}

}  // namespace sculpt::haptics
