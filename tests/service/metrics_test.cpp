#include <afr/display/service/metrics.h>
#include <afr/display/service/metrics_exposition.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace afr::service {
namespace {

TEST(LatencyHistogramTest, QuantilesMatchSortedReferenceWithinABin) {
  std::mt19937 rng(3);
  std::exponential_distribution<double> d(1.0 / 0.02);
  LatencyHistogram h;
  std::vector<double> all;
  for (int i = 0; i < 20000; ++i) {
    const double v = std::min(d(rng), 1.9);
    all.push_back(v);
    h.add(v, 1);
  }
  std::sort(all.begin(), all.end());
  for (double q : {0.5, 0.9, 0.99}) {
    const double ref = all[size_t(std::ceil(q * all.size())) - 1];
    EXPECT_NEAR(h.quantile(q), ref, LatencyHistogram::kBin) << q;
  }
}

TEST(ServiceMetricsTest, SequenceGapsCountMissingBatchesNotRestarts) {
  ServiceMetrics m;
  SampleBatch b;
  b.sampler_id = 4;
  b.samples.resize(3);
  for (uint64_t s : {0, 1, 2, 5, 6, 0, 1}) {  // 3 and 4 missing; then a restart
    b.sequence = s;
    m.on_batch(b, 100, true);
  }
  const std::vector<SamplerMetrics> ss = m.samplers();
  ASSERT_EQ(ss.size(), 1u);
  EXPECT_EQ(ss[0].sequence_gaps, 2u);
  EXPECT_EQ(ss[0].samples, 21u);
  EXPECT_EQ(ss[0].batches, 7u);
}

TEST(ServiceMetricsTest, LatencyIsFrameTimeMinusSampleTime) {
  ServiceMetrics m;
  SampleBatch b;
  b.sampler_id = 1;
  b.samples.resize(10);
  for (Sample& s : b.samples) s.time = 5.0;
  m.on_batch(b, 10, true);
  m.on_frame(5.012, 1.0, 10, 100);
  EXPECT_NEAR(m.display().latency_p50, 0.012, 2 * LatencyHistogram::kBin);
  const std::string text = prometheus_text(m);
  EXPECT_NE(text.find("afr_sampler_samples_total{sampler=\"1\"} 10"), std::string::npos);
  EXPECT_NE(text.find("afr_display_sample_latency_seconds_count 10"), std::string::npos);
}

}  // namespace
}  // namespace afr::service
