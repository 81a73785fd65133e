/// @brief The Prometheus text writer.
#include "net/metrics.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace sculpt::server {
namespace {

std::string FormatValue(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[64];
  // Integers print without an exponent; other values with enough digits to round-trip.
  if (v == std::floor(v) && std::fabs(v) < 1e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
  } else {
    // The shortest form that reads back as the same double ("0.00025", not 0.00025000000000000001).
    for (int precision = 6; precision <= 17; ++precision) {
      std::snprintf(buf, sizeof buf, "%.*g", precision, v);
      if (std::strtod(buf, nullptr) == v) break;
    }
  }
  return buf;
}

void AppendEscaped(std::string_view s, bool help, std::string* out) {
  for (char c : s) {
    if (c == '\\') {
      *out += "\\\\";
    } else if (c == '\n') {
      *out += "\\n";
    } else if (c == '"' && !help) {
      *out += "\\\"";
    } else {
      *out += c;
    }
  }
}

}  // namespace

void MetricsWriter::Family(std::string_view name, std::string_view help, std::string_view type) {
  if (families_.count(name)) return;
  families_.emplace(name);
  out_ += "# HELP ";
  out_ += name;
  out_ += ' ';
  AppendEscaped(help, /*help=*/true, &out_);
  out_ += "\n# TYPE ";
  out_ += name;
  out_ += ' ';
  out_ += type;
  out_ += '\n';
}

void MetricsWriter::Sample(std::string_view name, const MetricLabels& labels, double value) {
  out_ += name;
  if (!labels.empty()) {
    out_ += '{';
    for (size_t i = 0; i < labels.size(); ++i) {
      if (i) out_ += ',';
      out_ += labels[i].first;
      out_ += "=\"";
      AppendEscaped(labels[i].second, /*help=*/false, &out_);
      out_ += '"';
    }
    out_ += '}';
  }
  out_ += ' ';
  out_ += FormatValue(value);
  out_ += '\n';
}

void MetricsWriter::Counter(std::string_view name, std::string_view help, double value,
                            const MetricLabels& labels) {
  Family(name, help, "counter");
  Sample(name, labels, value);
}

void MetricsWriter::Gauge(std::string_view name, std::string_view help, double value,
                          const MetricLabels& labels) {
  Family(name, help, "gauge");
  Sample(name, labels, value);
}

void MetricsWriter::Histogram(std::string_view name, std::string_view help,
                              const LatencyHistogram::Snapshot& h, const MetricLabels& labels) {
  Family(name, help, "histogram");
  const std::string base(name);
  for (size_t i = 0; i < LatencyHistogram::kBounds.size(); ++i) {
    MetricLabels l = labels;
    l.emplace_back("le", FormatValue(LatencyHistogram::kBounds[i]));
    Sample(base + "_bucket", l, static_cast<double>(h.cumulative[i]));
  }
  MetricLabels inf = labels;
  inf.emplace_back("le", "+Inf");
  Sample(base + "_bucket", inf, static_cast<double>(h.count));
  Sample(base + "_sum", labels, h.sum);
  Sample(base + "_count", labels, static_cast<double>(h.count));
}

}  // namespace sculpt::server
