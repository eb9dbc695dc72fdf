// A sampler handed over to another region (a recut, Sampler::set_region and
// SamplerPool::set_region): the crosshairs of the pixels it keeps stay as they were, only
// gained pixels get new ones, the fill of those goes one crosshair per step (so at whatever pace
// caps the loop), and the tiling is a partition of the new region with exact statistics.
#include <afr/common/error.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/sampler_pool.h>

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>
#include <vector>

#include "support/sampler_rig.h"
#include "support/test_scenes.h"
#include "support/tile_stats.h"

namespace afr {
namespace {

using testing::SamplerRig;

// What identifies a crosshair in a pixel's queue, newest first.
using Held = std::vector<std::tuple<double, float, float, float>>;

Held held(const Sampler& s, int32_t x, int32_t y) {
  Held out;
  for (int k = 0; k < s.buffer().count(x, y); ++k) {
    const Crosshair c = s.buffer().at(x, y, k);
    out.emplace_back(c.time, c.x, c.y, c.luminance);
  }
  return out;
}

struct Handover {
  const char* name;
  PixelRect from, to;
};

class RegionHandoverTest : public ::testing::TestWithParam<Handover> {};

TEST_P(RegionHandoverTest, KeepsKeptCrosshairsAndFillsOnlyGainedPixelsOnePerStep) {
  const Handover h = GetParam();
  SamplerConfig config;
  config.image = ImageExtent{64, 64};
  config.region = h.from;
  config.seed = 11;
  SamplerRig rig(testing::moving_scene(), 1e5, config);
  Sampler& sampler = rig.sampler;  // not a structured binding: the lambdas capture it
  sampler.fill();
  for (int k = 0; k < 3000; ++k) sampler.step();  // crosshairs of many times, tiles adjusted

  const PixelRect kept = intersect(h.from, h.to);
  std::vector<Held> before;
  for (int32_t y = kept.y0; y < kept.y1; ++y) {
    for (int32_t x = kept.x0; x < kept.x1; ++x) before.push_back(held(sampler, x, y));
  }
  const auto expect_kept_unchanged = [&](const char* when) {
    size_t i = 0;
    for (int32_t y = kept.y0; y < kept.y1; ++y) {
      for (int32_t x = kept.x0; x < kept.x1; ++x, ++i) {
        ASSERT_EQ(held(sampler, x, y), before[i]) << when << " at " << x << ", " << y;
      }
    }
  };
  const uint64_t samples = sampler.counters().samples;
  const uint64_t rays = rig.clock.rays();

  sampler.set_region(h.to);
  EXPECT_EQ(sampler.region(), h.to);
  EXPECT_EQ(sampler.counters().samples, samples) << "set_region traces nothing";
  EXPECT_EQ(rig.clock.rays(), rays);
  expect_kept_unchanged("after set_region");
  // The fill's grid over the gained pixels, and nothing else there yet.
  std::set<std::pair<int32_t, int32_t>> grid;
  for (int32_t y = h.to.y0; y < h.to.y1; ++y) {
    for (int32_t x = h.to.x0; x < h.to.x1; ++x) {
      if (h.from.contains(x, y)) continue;
      EXPECT_EQ(sampler.buffer().count(x, y), 0);
      if ((x - h.to.x0) % config.fill_step == 0 && (y - h.to.y0) % config.fill_step == 0) {
        grid.insert({x, y});
      }
    }
  }
  EXPECT_EQ(sampler.handover_remaining(), int64_t(grid.size()));
  ASSERT_TRUE(sampler.tiling().is_valid());
  EXPECT_EQ(sampler.tiling().region(), h.to);
  EXPECT_GE(sampler.tiling().tile_count(), sampler.config().min_tiles);
  EXPECT_LE(sampler.tiling().tile_count(), sampler.config().max_tiles);
  for (int t : sampler.tiling().tiles()) {
    const TileStats inc = sampler.tile_stats(t);
    const TileStats ref = testing::brute_force_stats(sampler, t, rig.clock.now());
    ASSERT_EQ(inc.count, ref.count);
    EXPECT_NEAR(inc.v, ref.v, 1e-6 * std::max(1e-6, ref.v));
    EXPECT_NEAR(inc.G_t, ref.G_t, 1e-6 * std::max(1e-6, ref.G_t));
  }

  // One crosshair (at most 5 samples) per step until the gained pixels are filled: the fill
  // goes at the loop's pace, which is what the pool's rate cap paces.
  int64_t steps = 0;
  while (sampler.handover_remaining() > 0) {
    const uint64_t at = sampler.counters().samples;
    sampler.step();
    ++steps;
    ASSERT_LE(sampler.counters().samples - at, 5u);
  }
  EXPECT_EQ(steps, int64_t(grid.size()));
  expect_kept_unchanged("after the fill");
  for (int32_t y = h.to.y0; y < h.to.y1; ++y) {
    for (int32_t x = h.to.x0; x < h.to.x1; ++x) {
      if (h.from.contains(x, y)) continue;
      const bool on_grid = grid.count({x, y}) > 0;
      ASSERT_EQ(sampler.buffer().count(x, y), on_grid ? 1 : 0) << x << ", " << y;
      if (on_grid) {
        const Crosshair c = sampler.buffer().at(x, y, 0);
        EXPECT_EQ(c.x, float(x + 0.5));
        EXPECT_EQ(c.y, float(y + 0.5));
      }
    }
  }

  // The loop goes on over the new region.
  for (int k = 0; k < 3000; ++k) sampler.step();
  EXPECT_TRUE(sampler.tiling().is_valid());
  EXPECT_EQ(sampler.snapshot().region, h.to);
  for (const Sample& s :
       std::vector<Sample>(rig.sink.samples.end() - 500, rig.sink.samples.end())) {
    // Neighbours of a crosshair reach one pixel out of the region.
    EXPECT_GE(s.x, float(h.to.x0 - 1));
    EXPECT_LT(s.x, float(h.to.x1 + 1));
  }
}

INSTANTIATE_TEST_SUITE_P(Handovers, RegionHandoverTest,
                         ::testing::Values(Handover{"Shrinks", {0, 0, 64, 64}, {8, 0, 40, 48}},
                                           Handover{"Grows", {16, 16, 48, 48}, {0, 0, 64, 64}},
                                           Handover{"Moves", {0, 0, 32, 64}, {20, 0, 52, 64}},
                                           Handover{"MovesAway", {0, 0, 32, 32}, {32, 32, 64, 64}}),
                         [](const ::testing::TestParamInfo<Handover>& info) {
                           return std::string(info.param.name);
                         });

TEST(RegionHandoverTest, BeforeFillOnlyMovesTheRegion) {
  SamplerConfig config;
  config.image = ImageExtent{32, 32};
  config.region = PixelRect{0, 0, 16, 32};
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  rig.sampler.set_region(PixelRect{16, 0, 32, 32});
  EXPECT_EQ(rig.sampler.handover_remaining(), 0);
  rig.sampler.fill();
  EXPECT_EQ(rig.sampler.buffer().size(), 8 * 16);
  EXPECT_EQ(rig.sampler.buffer().region(), (PixelRect{16, 0, 32, 32}));
}

struct CountingSink : SampleSink {
  std::mutex mutex;
  uint64_t samples = 0;
  std::vector<PixelRect> snapshot_regions;
  void on_batch(SampleBatch&& b) override {
    std::lock_guard<std::mutex> lock(mutex);
    samples += b.samples.size();
  }
  void on_tiling(TilingSnapshot&& s) override {
    std::lock_guard<std::mutex> lock(mutex);
    snapshot_regions.push_back(s.region);
  }
  uint64_t count() {
    std::lock_guard<std::mutex> lock(mutex);
    return samples;
  }
};

TEST(SamplerPoolHandoverTest, TwoThreadsMoveWithoutABurst) {
  const Scene scene = testing::moving_scene();
  WallClock clock;
  CountingSink sink;
  SamplerConfig config;
  config.image = ImageExtent{64, 32};
  config.region = PixelRect{0, 0, 32, 32};
  SamplerPoolOptions options;
  options.threads = 2;
  options.max_samples_per_second = 2000.0;
  SamplerPool pool(scene, config, options, clock, sink);
  pool.start();
  // The initial fill (640 samples a thread) is waited off at 1000 samples/s a thread.
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  const uint64_t before = sink.count();
  const auto start = std::chrono::steady_clock::now();
  pool.set_region(PixelRect{32, 0, 64, 32});
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const uint64_t after = sink.count();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // Every pixel is gained: a new pool's fill would emit 1280 samples at once. Here no more than
  // the cap allows, plus what a worker may catch up (50 ms), a batch in flight and a step per
  // thread. Upper bounds only: a busy machine samples less.
  EXPECT_LE(double(after - before), 2000.0 * (seconds + 0.05) + 2 * 128 + 2 * 16);
  EXPECT_LT(after - before, 1280u);

  ASSERT_EQ(pool.regions().size(), 2u);
  EXPECT_EQ(pool.region(), (PixelRect{32, 0, 64, 32}));
  EXPECT_EQ(intersect(pool.regions()[0], pool.regions()[1]), PixelRect{});
  EXPECT_EQ(pool.regions()[0].area() + pool.regions()[1].area(), 32 * 32);
  // A second handover, back over half of the old region: each worker keeps what it shares.
  pool.set_region(PixelRect{16, 0, 48, 32});
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  pool.stop();
  bool saw[2] = {false, false};
  {
    std::lock_guard<std::mutex> lock(sink.mutex);
    for (const PixelRect& r : sink.snapshot_regions) {
      for (int k = 0; k < 2; ++k) saw[k] |= r == pool.regions()[k];
    }
  }
  EXPECT_TRUE(saw[0] && saw[1]) << "both workers sample their new sub-regions";
  for (const PixelRect& r : pool.regions()) {
    EXPECT_EQ(intersect(r, PixelRect{16, 0, 48, 32}), r);
  }
}

TEST(SamplerPoolHandoverTest, WorkersTakeThePartTheyShareMostWith) {
  const Scene scene = testing::edge_scene();
  WallClock clock;
  CountingSink sink;
  SamplerConfig config;
  config.image = ImageExtent{64, 32};
  SamplerPoolOptions options;
  options.threads = 2;
  SamplerPool pool(scene, config, options, clock, sink);
  ASSERT_EQ(pool.regions()[0], (PixelRect{0, 0, 32, 32}));
  // The right three quarters split into [16, 40) and [40, 64): worker 0 shares 16 columns with
  // the first, worker 1 all of the second.
  pool.set_region(PixelRect{16, 0, 64, 32});
  EXPECT_EQ(pool.regions()[0], (PixelRect{16, 0, 40, 32}));
  EXPECT_EQ(pool.regions()[1], (PixelRect{40, 0, 64, 32}));
  EXPECT_THROW(pool.set_region(PixelRect{60, 0, 70, 32}), Error);  // outside the image
  EXPECT_THROW(pool.set_region(PixelRect{0, 0, 1, 1}), Error);     // fewer pixels than threads
}

}  // namespace
}  // namespace afr
