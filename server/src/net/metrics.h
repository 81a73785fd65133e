/// @brief Metrics for /metrics: a writer of the Prometheus text exposition format (version
/// 0.0.4); the histograms it writes are sculpt::LatencyHistogram.
#ifndef SCULPT_SERVER_NET_METRICS_H_
#define SCULPT_SERVER_NET_METRICS_H_

#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sculpt/core/latency_histogram.h"

namespace sculpt::server {

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
