#include "net/metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "integration/prometheus_text.h"

namespace sculpt::server {
namespace {

TEST(LatencyHistogramTest, CountsCumulativelyAndEstimatesQuantiles) {
  LatencyHistogram h;
  for (int i = 0; i < 90; ++i) h.Observe(0.0008);  // <= 1 ms
  for (int i = 0; i < 10; ++i) h.Observe(0.03);    // <= 50 ms
  h.Observe(-1);                                    // counted as 0
  h.Observe(100);                                   // above every bound
  const auto s = h.Read();
  EXPECT_EQ(s.count, 102u);
  ASSERT_EQ(LatencyHistogram::kBounds[4], 0.001);
  EXPECT_EQ(s.cumulative[4], 91u);  // le 0.001
  EXPECT_EQ(s.cumulative.back(), 101u);
  EXPECT_NEAR(s.sum, 90 * 0.0008 + 10 * 0.03 + 100, 1e-6);
  EXPECT_DOUBLE_EQ(s.Quantile(0.5), 0.001);
  EXPECT_DOUBLE_EQ(s.Quantile(0.95), 0.05);
  EXPECT_TRUE(std::isinf(s.Quantile(1.0)));
}

TEST(MetricsWriterTest, WritesAPageAStrictParserAccepts) {
  MetricsWriter w;
  w.Counter("a_total", "An \"a\" with a \\ and\nnewline", 3);
  w.Gauge("b", "B", 1.5, {{"role", "vie\"wer"}, {"transport", "ws"}});
  w.Gauge("b", "B", 0, {{"role", "sculptor"}, {"transport", "tcp"}});
  LatencyHistogram h;
  h.Observe(0.002);
  w.Histogram("c_seconds", "C", h.Read(), {{"transport", "tcp"}});
  sculpt::testing::PromPage page;
  std::string error;
  ASSERT_TRUE(sculpt::testing::ParsePrometheusText(w.text(), &page, &error)) << error << "\n"
                                                                               << w.text();
  EXPECT_EQ(page.types["a_total"], "counter");
  EXPECT_EQ(page.Value("b", {{"role", "vie\"wer"}, {"transport", "ws"}}), 1.5);
  EXPECT_EQ(page.Value("c_seconds_bucket", {{"transport", "tcp"}, {"le", "0.002"}}), 1);
  EXPECT_EQ(page.Value("c_seconds_bucket", {{"transport", "tcp"}, {"le", "0.001"}}), 0);
  EXPECT_EQ(page.Value("c_seconds_count", {{"transport", "tcp"}}), 1);
}

TEST(PrometheusParserTest, RejectsInterleavedFamiliesAndBadLines) {
  sculpt::testing::PromPage page;
  std::string error;
  EXPECT_FALSE(sculpt::testing::ParsePrometheusText(
      "# TYPE a gauge\na 1\n# TYPE b gauge\nb 1\na 2\n", &page, &error));
  page = {};
  EXPECT_FALSE(sculpt::testing::ParsePrometheusText("a 1\n", &page, &error));  // no TYPE
  page = {};
  EXPECT_FALSE(sculpt::testing::ParsePrometheusText("# TYPE a gauge\na{x=\"1} 1\n", &page, &error));
  page = {};
  EXPECT_FALSE(sculpt::testing::ParsePrometheusText("# TYPE a counter\na -1\n", &page, &error));
}

}  // namespace
}  // namespace sculpt::server
