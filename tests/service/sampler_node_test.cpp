// sampler_node as a service: back after its display restarts, bounded memory while the display
// stalls, an unreachable display reported, flags checked and winning over the display's preset.
#include "service_fixture.h"

#include <gtest/gtest.h>

namespace afr::testing {
namespace {

TEST_F(ServiceTest, SamplersAreBackWithinTwoSecondsOfADisplayRestart) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display1.log");
  auto s1 = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  auto s2 = sampler({"--max-samples-per-second", "50000"}, "s2.log");
  ASSERT_TRUE(wait_members(2, 5.0)) << d->log();
  const std::string session = get_stats(metrics_port())["display"]["session"];
  d->signal(SIGKILL);
  d->wait(2.0);
  auto d2 = display({"--size", "64x64", "--fps", "20"}, "display2.log");
  ASSERT_TRUE(wait_members(2, scaled(4.0))) << d2->log() << s1->log() << s2->log();
  // From the new display's bind (its first log line about its sockets) to its second join.
  const double bound = log_time(d2->log(), "display session");
  const double back = log_time(d2->log(), " joined: ", 2);
  ASSERT_GE(bound, 0.0) << d2->log();
  ASSERT_GE(back, 0.0) << d2->log();
  const double took = seconds_between(bound, back);
  std::printf("samplers back %.3f s after the display bound its sockets\n", took);
  EXPECT_LT(took, scaled(2.0)) << d2->log() << s1->log() << s2->log();
  EXPECT_NE(get_stats(metrics_port())["display"]["session"], session);
  // The scene was loaded once, before the restart: sent by the display, or found in the cache
  // the other sampler filled. After the restart the sampler kept it (same hash).
  for (const auto* s : {s1.get(), s2.get()}) {
    const std::string log = s->log();
    EXPECT_EQ(count_of(log, "scene received") + count_of(log, "found in the cache"), 1u) << log;
  }
}

TEST_F(ServiceTest, StalledDisplayKeepsSamplerMemoryBoundedAndCountsDrops) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const long rss0 = s->rss_kb();
  d->signal(SIGSTOP);  // the display stops reading: its socket buffers and queues fill
  long rss_max = rss0;
  for (int i = 0; i < 30; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    rss_max = std::max(rss_max, s->rss_kb());
  }
  d->signal(SIGCONT);
  std::printf("sampler RSS %ld kB before the stall, at most %ld kB during 3 s of it\n", rss0,
              rss_max);
  EXPECT_LT(rss_max - rss0, 64 * 1024) << "sampler memory grew while the display was stalled";
  const bool counted = wait_until(
      [&] {
        const auto st = get_stats(metrics_port());
        if (st.is_null() || st.is_discarded()) return false;
        for (const auto& m : st["samplers"]) {
          if (m["batches_dropped"].get<uint64_t>() > 0) return true;
        }
        return false;
      },
      5.0);
  EXPECT_TRUE(counted) << d->log() << s->log();
}

TEST_F(ServiceTest, SamplerFlagOutOfRangeIsNamedAndTheDisplayKeepsServing) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  auto bad = sampler({"--kappa", "2"}, "bad.log");
  EXPECT_NE(bad->wait(10.0), 0);
  EXPECT_NE(bad->log().find("kappa = 2 is outside [0, 1]"), std::string::npos) << bad->log();
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
}

TEST_F(ServiceTest, UnreachableDisplayIsReportedAndTheSamplerKeepsTrying) {
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_until(
      [&] { return s->log().find("no answer from the display") != std::string::npos; }, 10.0))
      << s->log();
  EXPECT_TRUE(s->alive());
  // The display comes up late: the sampler joins it.
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  EXPECT_TRUE(wait_members(1, 15.0)) << d->log() << s->log();
}

TEST_F(ServiceTest, SamplerFlagsGivenExplicitlyWinOverTheDisplaysPreset) {
  // The display names the fast preset (r = 2, chunk 100); the sampler is given --b 1 and
  // --chunk 50 and keeps those, taking the rest (r) from the preset.
  auto d = display({"--size", "64x64", "--preset", "fast"}, "display.log");
  auto s = sampler({"--b", "1", "--chunk", "50", "--max-samples-per-second", "20000"}, "s.log");
  ASSERT_TRUE(wait_until([&] { return s->log().find("sampler knobs:") != std::string::npos; }, 5.0))
      << s->log();
  const std::string log = s->log();
  EXPECT_NE(log.find("preset fast, b = 1, r = 2, chunk = 50"), std::string::npos) << log;
}

}  // namespace
}  // namespace afr::testing
