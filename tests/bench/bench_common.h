/// @brief Shared helpers of sculpt-bench: sample statistics, timing, random directions, progress.
#ifndef SCULPT_TESTS_BENCH_BENCH_COMMON_H_
#define SCULPT_TESTS_BENCH_BENCH_COMMON_H_

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"

namespace sculpt::bench {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

inline double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// Percentile q in [0, 1] by linear interpolation between order statistics (Hyndman-Fan type 7,
/// numpy's default). NaN for an empty sample.
inline double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

/// A sample of durations (or any values) with the usual summary.
struct Samples {
  std::vector<double> values;
  void Add(double x) { values.push_back(x); }
  size_t size() const { return values.size(); }
  double P(double q) const { return Percentile(values, q); }
  double Mean() const {
    if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
    double s = 0;
    for (double x : values) s += x;
    return s / static_cast<double>(values.size());
  }
  double Max() const {
    return values.empty() ? std::numeric_limits<double>::quiet_NaN()
                          : *std::max_element(values.begin(), values.end());
  }
  double Min() const {
    return values.empty() ? std::numeric_limits<double>::quiet_NaN()
                          : *std::min_element(values.begin(), values.end());
  }
  Json Summary() const {
    return Json{{"n", values.size()}, {"p50", P(0.5)},  {"p90", P(0.9)}, {"p99", P(0.99)},
                {"mean", Mean()},     {"min", Min()},   {"max", Max()}};
  }
};

/// A uniformly distributed unit vector (normal deviates, normalised).
inline Vec3 RandomDirection(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (;;) {
    const Vec3 v{n(rng), n(rng), n(rng)};
    const double l = v.Length();
    if (l > 1e-9) return v / l;
  }
}

/// One progress line on stderr.
inline void Progress(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
inline void Progress(const char* fmt, ...) {
  std::fprintf(stderr, "[sculpt-bench] ");
  va_list ap;
  va_start(ap, fmt);
  std::vfprintf(stderr, fmt, ap);
  va_end(ap);
  std::fputc('\n', stderr);
  std::fflush(stderr);
}

inline std::string StatusText(const Status& s) { return s.ok() ? "ok" : s.ToString(); }

/// Options of `sculpt-bench edit`.
struct EditBenchOptions {
  bool quick = false;
  std::vector<double> radii{64, 128, 256, 512};
  int edits = 1000;  // timed edits per kind per radius
  int warmup = 5;   // untimed edits per kind per radius
  std::vector<double> naive_radii{64, 128};
  int naive_edits = 5;
  int strokes = 10000;
  double stroke_radius = 64;
  int checkpoint_every = 500;
  double tool_radius = 5;   // voxels
  double penetration = 2;   // voxels
  uint64_t seed = 20240601;
  bool skip_strokes = false;
  std::vector<std::string> kinds;  // edit kinds to run (press, add, ...); empty: all
  bool repair_band_every_edit = false;  // EditSettings::repair_band_every_edit
};

/// Options of `sculpt-bench accuracy`.
struct AccuracyBenchOptions {
  bool quick = false;
  double sphere_radius = 16;  // world units
  double tool_radius = 3;     // world units
  double penetration = 1.0;   // world units
  int strokes = 20;
  int repeats = 3;  // scenario runs per configuration; the time is the median of their means
  double base_voxel = 0.5;
  std::vector<double> voxel_sizes{1.0, 0.5, 0.25};
  double reference_voxel = 0.125;
  bool scheme_grid = true;  // every spatial x temporal pair at the base voxel size
  std::string out_dat;
};

Json RunEditBench(const EditBenchOptions& o);
Json RunAccuracyBench(const AccuracyBenchOptions& o);

}  // namespace sculpt::bench

#endif  // SCULPT_TESTS_BENCH_BENCH_COMMON_H_
