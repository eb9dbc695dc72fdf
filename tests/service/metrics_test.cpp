#include <afr/display/service/metrics.h>
#include <afr/display/service/metrics_exposition.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/promtool.h"

#include <algorithm>
#include <random>
#include <set>
#include <sstream>
#include <string>

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

// A peer that makes up sampler ids cannot grow the per-sampler state: batches and tilings
// from non-members are counted in the display's figures alone.
TEST(ServiceMetricsTest, NonMembersGetNoPerSamplerState) {
  ServiceMetrics m;
  m.on_member("real", 1, "", 1);
  SampleBatch b;
  b.samples.resize(4);
  for (uint32_t id = 100; id < 100100; ++id) {
    b.sampler_id = id;
    m.on_batch(b, 50, false);
    m.on_tiling(id, 30, false);
  }
  b.sampler_id = 1;
  m.on_batch(b, 50, true);
  const std::vector<SamplerMetrics> ss = m.samplers();
  ASSERT_EQ(ss.size(), 1u);
  EXPECT_EQ(ss[0].id, 1u);
  EXPECT_EQ(ss[0].samples, 4u);
  EXPECT_EQ(m.display().unknown_sampler_batches, 100000u);
  EXPECT_EQ(m.display().unknown_sampler_samples, 400000u);
  EXPECT_LT(prometheus_text(m).size(), size_t(20000));
}

// Stats are filed under the member whose control connection sent them, whatever id they claim.
TEST(ServiceMetricsTest, StatsAreFiledUnderTheSendingMember) {
  ServiceMetrics m;
  m.on_member("a", 2, "", 1);
  protocol::SamplerStats claimed;
  claimed.sampler_id = 99;
  claimed.samples_per_second = 1e300;
  m.on_reported(2, claimed);
  const std::vector<SamplerMetrics> ss = m.samplers();
  ASSERT_EQ(ss.size(), 1u);
  EXPECT_EQ(ss[0].id, 2u);
  EXPECT_EQ(ss[0].reported.sampler_id, 2u);
}

TEST(ServiceMetricsTest, DepartedSamplersAreForgottenAfterTheGrace) {
  ServiceMetrics m;
  m.on_member("leaves", 1, "", 1);
  m.on_member("stays", 2, "", 1);
  m.on_member_gone(1, false);
  for (int p = 0; p < ServiceMetrics::kDepartedPeriods; ++p) m.end_period(2.0);
  EXPECT_EQ(m.samplers().size(), 2u);  // its last figures, for a while
  m.end_period(2.0);
  const std::vector<SamplerMetrics> ss = m.samplers();
  ASSERT_EQ(ss.size(), 1u);
  EXPECT_EQ(ss[0].id, 2u);
  // One that comes back before the grace ends starts counting again when it leaves again.
  m.on_member("back", 3, "", 1);
  m.on_member_gone(3, true);
  for (int p = 0; p < 10; ++p) m.end_period(2.0);
  m.on_member("back", 3, "", 1);
  for (int p = 0; p < 2 * ServiceMetrics::kDepartedPeriods; ++p) m.end_period(2.0);
  EXPECT_EQ(m.samplers().size(), 2u);
}

// Samplers that join and leave in a loop leave at most kMaxDeparted departed entries behind
// (the longest gone and, among those gone as long, the first to join go first); the members
// keep theirs.
TEST(ServiceMetricsTest, DepartedSamplersBeyondTheBoundGoOldestFirst) {
  ServiceMetrics m;
  m.on_member("stays", 1, "", 1);
  m.on_member("early", 2, "", 1);
  m.on_member_gone(2, false);
  m.end_period(2.0);  // sampler 2 is now the longest gone
  const uint32_t churned = 1000;
  for (uint32_t id = 3; id < 3 + churned; ++id) {
    m.on_member("churn", id, "", 1);
    m.on_member_gone(id, false);
  }
  const std::vector<SamplerMetrics> ss = m.samplers();
  ASSERT_EQ(ss.size(), 1u + ServiceMetrics::kMaxDeparted);
  EXPECT_EQ(m.display().members, 1u);
  EXPECT_EQ(m.display().joins, 2u + churned);
  std::vector<uint32_t> ids;
  for (const SamplerMetrics& s : ss) ids.push_back(s.id);
  EXPECT_TRUE(std::find(ids.begin(), ids.end(), 1u) != ids.end());  // the member
  EXPECT_TRUE(std::find(ids.begin(), ids.end(), 2u) == ids.end());  // the longest gone
  // The newest departed remain.
  for (uint32_t id = 3 + churned - uint32_t(ServiceMetrics::kMaxDeparted); id < 3 + churned; ++id) {
    EXPECT_TRUE(std::find(ids.begin(), ids.end(), id) != ids.end()) << id;
  }
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

// A service with two members, frames, latencies, a GPU backend and a wall cell: every family
// of the exposition has series.
void make_busy(ServiceMetrics& m) {
  m.on_member("a", 1, "", 2);
  m.on_member("b", 2, "", 4);
  m.on_region(1, PixelRect{0, 0, 64, 128}, 1, 0);
  m.on_region(2, PixelRect{64, 0, 128, 128}, 1, 0);
  for (uint32_t id : {1u, 2u}) {
    SampleBatch b;
    b.sampler_id = id;
    b.sequence = 1;
    b.samples.resize(100);
    for (Sample& s : b.samples) s.time = 1.0;
    m.on_batch(b, 3000, true);
  }
  GpuTimes gpu;
  gpu.timed = true;
  gpu.upload = 0.5;
  gpu.splat = 2.0;
  m.set_gpu(gpu);
  m.add_call(CallTimes{0.1, 0.2, 3.0, 0.4, 0.5});
  m.set_image_counts(12, 3);
  m.set_wall(0, PixelRect{0, 0, 128, 128}, 1, 1);
  for (int i = 0; i < 30; ++i) m.on_frame(1.01 + 0.02 * i, 4.0 + i, 200, 1000);
  m.end_period(1.0);
}

// The series names (with their labels) of an exposition, comments left out.
std::set<std::string> series(const std::string& text) {
  std::set<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    out.insert(line.substr(0, line.rfind(' ')));
  }
  return out;
}

// The scene's transfer to a member, for the dashboard's progress: in /stats, members only.
// A GPU backend's call phases: each the mean over the stats period, in /stats, the
// exposition and the log line; a CPU backend (phases all zero) shows none, and a period
// without calls clears the figures.
TEST(ServiceMetricsTest, CallPhasesAreMeansOverThePeriodAndAbsentWithoutAGpuBackend) {
  ServiceMetrics m;
  m.add_call(CallTimes{});  // the CPU backend's
  m.end_period(1.0);
  EXPECT_TRUE(nlohmann::json::parse(stats_json(m))["display"]["period_call_ms"].is_null());
  EXPECT_EQ(prometheus_text(m).find("afr_display_period_call_phase_seconds"), std::string::npos);
  EXPECT_EQ(stats_line(m).find("(call:"), std::string::npos);

  m.add_call(CallTimes{1.0, 2.0, 10.0, 4.0, 0.5});
  m.add_call(CallTimes{3.0, 2.0, 20.0, 2.0, 1.5});
  m.end_period(1.0);
  const nlohmann::json call = nlohmann::json::parse(stats_json(m))["display"]["period_call_ms"];
  EXPECT_DOUBLE_EQ(call["wait"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(call["copy"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(call["prepare"].get<double>(), 15.0);
  EXPECT_DOUBLE_EQ(call["upload"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(call["passes"].get<double>(), 1.0);
  EXPECT_NE(
      prometheus_text(m).find("afr_display_period_call_phase_seconds{phase=\"prepare\"} 0.015"),
      std::string::npos)
      << prometheus_text(m);
  EXPECT_NE(stats_line(m).find("(call: wait 2.0 copy 2.0 prepare 15.0 upload 3.0 passes 1.0 ms)"),
            std::string::npos)
      << stats_line(m);

  m.end_period(1.0);
  EXPECT_TRUE(nlohmann::json::parse(stats_json(m))["display"]["period_call_ms"].is_null());
}

TEST(ServiceMetricsTest, SceneTransferProgressIsInStats) {
  ServiceMetrics m;
  m.on_member("a", 1, "", 1);
  m.on_scene_progress(1, 3, 12);
  m.on_scene_progress(99, 1, 2);  // no member: no state
  const nlohmann::json st = nlohmann::json::parse(stats_json(m));
  ASSERT_EQ(st["samplers"].size(), 1u);
  EXPECT_EQ(st["samplers"][0]["scene"]["chunks_sent"].get<int>(), 3);
  EXPECT_EQ(st["samplers"][0]["scene"]["chunks"].get<int>(), 12);
}

TEST(ServiceMetricsTest, PromtoolAcceptsTheExposition) {
  // promtool (Debian package prometheus, installed by deploy/install-deps.sh) checks the text
  // format and the naming conventions: base units, _total on counters. The live exposition is
  // checked too (HostilePeerTest.SpoofedAndNonMemberBatchesAreDroppedAndCounted).
  ServiceMetrics m;
  make_busy(m);
  const auto verdict = testing::promtool_check_metrics(prometheus_text(m));
  if (!verdict) GTEST_SKIP() << "promtool is not installed (Debian package prometheus)";
  EXPECT_EQ(verdict->status, 0) << verdict->output;
  EXPECT_EQ(verdict->output, "");
}

TEST(ServiceMetricsTest, UnitsAreSecondsAndRecutsStartNoNewSeries) {
  ServiceMetrics m;
  make_busy(m);
  const std::string before = prometheus_text(m);
  // 30 reconstructions of 4-33 ms: the histogram in seconds, the last one as a gauge.
  EXPECT_NE(before.find("afr_display_reconstruct_seconds_count 30"), std::string::npos) << before;
  EXPECT_NE(before.find("afr_display_reconstruct_seconds_bucket{le=\"0.01\"} 6"),
            std::string::npos);
  EXPECT_NE(before.find("afr_display_last_reconstruct_seconds 0.033"), std::string::npos);
  EXPECT_NE(before.find("afr_display_gpu_pass_seconds{pass=\"splat\"} 0.002"), std::string::npos);
  EXPECT_NE(before.find("afr_display_hole_pixels 12"), std::string::npos);
  EXPECT_NE(before.find("afr_display_empty_pixels 3"), std::string::npos);
  EXPECT_NE(before.find("afr_sampler_region_edge_pixels{edge=\"x1\",sampler=\"1\"} 64"),
            std::string::npos);
  EXPECT_EQ(before.find("_ms"), std::string::npos) << "a metric in milliseconds";
  // A recut moves the regions: the same series carry the new edges.
  m.on_region(1, PixelRect{0, 0, 80, 128}, 2, 1);
  m.on_region(2, PixelRect{80, 0, 128, 128}, 2, 1);
  const std::string after = prometheus_text(m);
  EXPECT_EQ(series(before), series(after));
  EXPECT_NE(after.find("afr_sampler_region_edge_pixels{edge=\"x1\",sampler=\"1\"} 80"),
            std::string::npos);
}

}  // namespace
}  // namespace afr::service
