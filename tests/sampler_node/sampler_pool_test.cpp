#include <afr/sampler/sampler_pool.h>

#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <mutex>
#include <thread>

#include "support/test_scenes.h"

namespace afr {
namespace {

struct LockedSink : SampleSink {
  std::mutex mutex;
  uint64_t samples = 0;
  uint64_t snapshots = 0;
  std::vector<PixelRect> snapshot_regions;
  void on_batch(SampleBatch&& b) override {
    std::lock_guard<std::mutex> lock(mutex);
    samples += b.samples.size();
  }
  void on_tiling(TilingSnapshot&& s) override {
    std::lock_guard<std::mutex> lock(mutex);
    ++snapshots;
    snapshot_regions.push_back(s.region);
  }
};

TEST(SamplerPoolTest, ThreadsOwnDisjointRegionsAndAllProduce) {
  const Scene scene = testing::moving_scene();
  WallClock clock;
  LockedSink sink;
  SamplerConfig config;
  config.image.width = 64;
  config.image.height = 32;
  SamplerPoolOptions options;
  options.threads = 2;
  SamplerPool pool(scene, config, options, clock, sink);
  ASSERT_EQ(pool.regions().size(), 2u);
  EXPECT_EQ(pool.regions()[0], (PixelRect{0, 0, 32, 32}));
  EXPECT_EQ(pool.regions()[1], (PixelRect{32, 0, 64, 32}));
  pool.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  pool.stop();
  const SamplerCounters c = pool.counters();
  EXPECT_GT(c.samples, 1000u);
  EXPECT_EQ(c.samples, sink.samples);
  bool saw[2] = {false, false};
  for (const PixelRect& r : sink.snapshot_regions) {
    for (int k = 0; k < 2; ++k) saw[k] |= r == pool.regions()[k];
  }
  EXPECT_TRUE(saw[0] && saw[1]);
}

// The threads that trace (the sink hears from them) take the priority the options give; the
// thread that made the pool keeps its own.
TEST(SamplerPoolTest, WorkersRunNicedOrIdleAndTheCallerKeepsItsPriority) {
  struct PrioritySink : LockedSink {
    int policy = -1, nice = 0;
    void on_batch(SampleBatch&& b) override {
      const int p = ::sched_getscheduler(0);
      const int n = ::getpriority(PRIO_PROCESS, id_t(::syscall(SYS_gettid)));
      std::lock_guard<std::mutex> lock(mutex);
      samples += b.samples.size();
      policy = p;
      nice = n;
    }
  };
  const int caller_policy = ::sched_getscheduler(0);
  const int caller_nice = ::getpriority(PRIO_PROCESS, id_t(::syscall(SYS_gettid)));
  for (const bool idle : {false, true}) {
    SCOPED_TRACE(idle ? "SCHED_IDLE" : "nice");
    const Scene scene = testing::edge_scene();
    WallClock clock;
    PrioritySink sink;
    SamplerConfig config;
    config.image.width = 16;
    config.image.height = 16;
    SamplerPoolOptions options;
    options.worker_nice = idle ? 0 : 5;
    options.worker_idle = idle;
    SamplerPool pool(scene, config, options, clock, sink);
    pool.start();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    pool.stop();
    std::lock_guard<std::mutex> lock(sink.mutex);
    ASSERT_GT(sink.samples, 0u);
    if (idle) {
      EXPECT_EQ(sink.policy, SCHED_IDLE);
    } else {
      EXPECT_EQ(sink.policy, caller_policy);
      EXPECT_EQ(sink.nice, std::min(19, caller_nice + 5));
    }
  }
  EXPECT_EQ(::sched_getscheduler(0), caller_policy);
  EXPECT_EQ(::getpriority(PRIO_PROCESS, id_t(::syscall(SYS_gettid))), caller_nice);
}

TEST(SamplerPoolTest, RateCapHoldsSamplesBack) {
  const Scene scene = testing::edge_scene();
  WallClock clock;
  LockedSink sink;
  SamplerConfig config;
  config.image.width = 32;
  config.image.height = 32;
  SamplerPoolOptions options;
  options.threads = 2;
  options.max_samples_per_second = 20000.0;
  SamplerPool pool(scene, config, options, clock, sink);
  const auto start = std::chrono::steady_clock::now();
  pool.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  pool.stop();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // The initial fill (one crosshair every other pixel) comes before the cap applies; after it,
  // no more than the cap allows (plus one loop iteration per thread).
  const double fill = 16.0 * 16.0 * 5.0;
  EXPECT_LE(double(pool.counters().samples), fill + 20000.0 * seconds + 2 * 16);
}

// The pool's tracers pick among the lights as its options say (TracerOptions::light_samples):
// a grey wall under six point lights, each sample one shadow ray with 1, six without.
TEST(SamplerPoolTest, TracersPickAmongTheLightsAsTheOptionsSay) {
  Scene scene = testing::camera_scene();
  testing::add_quad(&scene, glm::vec3(0.0f), {-10, -10}, {10, 10}, -2.0f);
  scene.materials.back().base_color_factor = glm::vec4(0.5f, 0.5f, 0.5f, 1.0f);
  for (int i = 0; i < 6; ++i) {
    scene.lights.push_back(Light{});
    Node n;
    n.light = i;
    n.translation = glm::dvec3(-1.0 + 0.4 * i, 0.5, -0.5);
    scene.nodes.push_back(n);
  }
  scene.finalize();
  for (int k : {0, 1}) {
    SCOPED_TRACE(k);
    WallClock clock;
    LockedSink sink;
    SamplerConfig config;
    config.image.width = 32;
    config.image.height = 32;
    SamplerPoolOptions options;
    options.tracer.light_samples = k;
    SamplerPool pool(scene, config, options, clock, sink);
    pool.start();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    pool.stop();
    const SamplerCounters c = pool.counters();
    ASSERT_GT(c.samples, 100u);
    // Per sample emitted, within 10 %: a few per cent of the rays traced are not emitted (a
    // crosshair's arms beyond the image's border).
    const double per_sample = double(c.shadow_rays) / double(c.samples);
    const double expected = k == 0 ? 6.0 : 1.0;
    EXPECT_NEAR(per_sample, expected, 0.1 * expected);
  }
}

TEST(SamplerPoolTest, BadOptionsAreClearErrors) {
  const Scene scene = testing::edge_scene();
  WallClock clock;
  LockedSink sink;
  SamplerConfig config;
  config.image.width = 4;
  config.image.height = 1;
  SamplerPoolOptions options;
  options.threads = 8;  // more threads than pixels
  EXPECT_THROW(SamplerPool(scene, config, options, clock, sink), Error);
  options.threads = 0;
  EXPECT_THROW(SamplerPool(scene, config, options, clock, sink), Error);
  options.threads = 1;
  options.max_samples_per_second = -1.0;
  EXPECT_THROW(SamplerPool(scene, config, options, clock, sink), Error);
}

}  // namespace
}  // namespace afr
