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

TEST(ServiceMetricsTest, RefreshAndReconstructionFiguresCoverTheWholeStatsPeriod) {
  // 200 images in one period: 199 of 10 ms every 20 ms, then one of 50 ms after a 70 ms stall.
  // The period's figures see the whole interval, not the last frame; the next period starts
  // afresh.
  ServiceMetrics m;
  double t = 0.0;
  for (int i = 0; i < 199; ++i) {
    m.on_frame(t, 10.0, 0, 1);
    t += 0.02;
  }
  t += 0.05;
  m.on_frame(t, 50.0, 0, 1);
  m.end_period(4.0);
  DisplayMetrics d = m.display();
  EXPECT_NEAR(d.refresh_hz, 50.0, 1e-9);
  EXPECT_NEAR(d.period_reconstruct_ms_mean, (199 * 10.0 + 50.0) / 200.0, 1e-9);
  EXPECT_NEAR(d.period_reconstruct_ms_p99, 10.0, 0.2);  // 1 of 200 is above the 99th
  EXPECT_NEAR(d.period_frame_interval_ms_p99, 20.0, 0.2);
  EXPECT_NEAR(d.reconstruct_ms, 50.0, 1e-9);  // the last frame alone
  EXPECT_NE(stats_line(m).find("reconstruct mean 10.2 ms"), std::string::npos) << stats_line(m);
  for (int i = 0; i < 10; ++i) {
    t += 0.1;
    m.on_frame(t, 30.0, 0, 1);
  }
  m.end_period(1.0);
  d = m.display();
  EXPECT_NEAR(d.period_reconstruct_ms_mean, 30.0, 0.2);
  EXPECT_NEAR(d.period_frame_interval_ms_p99, 100.0, 0.2);
}

}  // namespace
}  // namespace afr::service
