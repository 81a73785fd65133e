/// @brief Metrics for /metrics: a lock-free latency histogram and a writer of the Prometheus
/// text exposition format (version 0.0.4).
#ifndef SCULPT_SERVER_NET_METRICS_H_
#define SCULPT_SERVER_NET_METRICS_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace sculpt::server {

/// A histogram of durations in seconds over fixed buckets (0.25 ms .. 10 s). Thread safety:
/// Observe from any thread; a reader sees each count atomically (the set may be mid-update).
class LatencyHistogram {
 public:
  static constexpr std::array<double, 15> kBounds = {
      0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05,
      0.1,     0.2,    0.5,   1.0,   2.0,   5.0,  10.0};

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

/// Labels of one sample, in order: {{"role", "viewer"}, {"transport", "ws"}}.
using MetricLabels = std::vector<std::pair<std::string, std::string>>;

/// Builds a Prometheus text page. Each family gets its HELP and TYPE lines once, before its
/// first sample; label values are escaped. Thread safety: none (one per scrape).
class MetricsWriter {
 public:
  void Counter(std::string_view name, std::string_view help, double value,
               const MetricLabels& labels = {});
  void Gauge(std::string_view name, std::string_view help, double value,
             const MetricLabels& labels = {});
  void Histogram(std::string_view name, std::string_view help,
                 const LatencyHistogram::Snapshot& h, const MetricLabels& labels = {});

  const std::string& text() const { return out_; }

 private:
  void Family(std::string_view name, std::string_view help, std::string_view type);
  void Sample(std::string_view name, const MetricLabels& labels, double value);

  std::string out_;
  std::set<std::string, std::less<>> families_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_METRICS_H_
