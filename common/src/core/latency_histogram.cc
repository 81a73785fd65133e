/// @brief LatencyHistogram: lock-free bucket counts and their cumulative read.
#include "sculpt/core/latency_histogram.h"

#include <cmath>
#include <limits>

namespace sculpt {

void LatencyHistogram::Observe(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) seconds = 0;
  size_t i = 0;
  while (i < kBounds.size() && seconds > kBounds[i]) ++i;
  buckets_[i].fetch_add(1, std::memory_order_relaxed);
  sum_ns_.fetch_add(static_cast<uint64_t>(std::llround(seconds * 1e9)), std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
}

LatencyHistogram::Snapshot LatencyHistogram::Read() const {
  Snapshot s;
  uint64_t running = 0;
  for (size_t i = 0; i < kBounds.size(); ++i) {
    running += buckets_[i].load(std::memory_order_relaxed);
    s.cumulative[i] = running;
  }
  // The count is the sum of the buckets read, so +Inf equals _count even mid-update.
  s.count = running + buckets_[kBounds.size()].load(std::memory_order_relaxed);
  s.sum = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) * 1e-9;
  return s;
}

double LatencyHistogram::Snapshot::Quantile(double q) const {
  if (count == 0) return 0;
  const double want = std::ceil(q * static_cast<double>(count));
  for (size_t i = 0; i < kBounds.size(); ++i) {
    if (static_cast<double>(cumulative[i]) >= want) return kBounds[i];
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace sculpt
