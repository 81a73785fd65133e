/// @brief LatencyHistogram: a lock-free histogram of durations over fixed buckets, shared by the
/// server's /metrics (stroke→ack latency) and the edit log (fdatasync time).
#ifndef SCULPT_CORE_LATENCY_HISTOGRAM_H_
#define SCULPT_CORE_LATENCY_HISTOGRAM_H_

#include <array>
#include <atomic>
#include <cstdint>

namespace sculpt {

/// A histogram of durations in seconds over fixed buckets (50 µs .. 10 s). Thread safety:
/// Observe from any thread; a reader sees each count atomically (the set may be mid-update).
class LatencyHistogram {
 public:
  static constexpr std::array<double, 17> kBounds = {
      0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02,
      0.05,    0.1,    0.2,     0.5,    1.0,   2.0,   5.0,   10.0};

  /// Negative or non-finite values are counted as 0.
  void Observe(double seconds);

  struct Snapshot {
    std::array<uint64_t, kBounds.size()> cumulative{};  // observations <= kBounds[i]
    uint64_t count = 0;
    double sum = 0;
    /// The bucket bound under which `q` (0..1) of the observations fall (an upper estimate);
    /// 0 when empty; +inf when above the last bound.
    double Quantile(double q) const;
  };
  Snapshot Read() const;

 private:
  std::array<std::atomic<uint64_t>, kBounds.size() + 1> buckets_{};  // last: above every bound
  std::atomic<uint64_t> count_{0};
  std::atomic<uint64_t> sum_ns_{0};
};

}  // namespace sculpt

#endif  // SCULPT_CORE_LATENCY_HISTOGRAM_H_
