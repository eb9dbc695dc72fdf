// The sampler's heap follows the region it owns, never the image: measured by counting every
// byte this program allocates (operator new is replaced here, which is why these tests are a
// binary of their own), not by what the sampler says it holds.
#include <afr/sampler/sampler.h>

#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>

#include "support/test_scenes.h"

namespace {

// Bytes live on the heap (through operator new) and the most since the last reset.
std::atomic<int64_t> g_live{0};
std::atomic<int64_t> g_peak{0};

void* counted(void* p) {
  if (p == nullptr) throw std::bad_alloc();
  const int64_t live = g_live += int64_t(malloc_usable_size(p));
  int64_t peak = g_peak.load();
  while (live > peak && !g_peak.compare_exchange_weak(peak, live)) {
  }
  return p;
}

void uncounted(void* p) {
  if (p == nullptr) return;
  g_live -= int64_t(malloc_usable_size(p));
  std::free(p);
}

void* aligned(std::size_t n, std::align_val_t a) {
  const std::size_t align = std::max(std::size_t(a), sizeof(void*));
  return std::aligned_alloc(align, (std::max<std::size_t>(n, 1) + align - 1) / align * align);
}

}  // namespace

void* operator new(std::size_t n) { return counted(std::malloc(std::max<std::size_t>(n, 1))); }
void* operator new[](std::size_t n) { return counted(std::malloc(std::max<std::size_t>(n, 1))); }
void* operator new(std::size_t n, std::align_val_t a) { return counted(aligned(n, a)); }
void* operator new[](std::size_t n, std::align_val_t a) { return counted(aligned(n, a)); }
void operator delete(void* p) noexcept { uncounted(p); }
void operator delete[](void* p) noexcept { uncounted(p); }
void operator delete(void* p, std::size_t) noexcept { uncounted(p); }
void operator delete[](void* p, std::size_t) noexcept { uncounted(p); }
void operator delete(void* p, std::align_val_t) noexcept { uncounted(p); }
void operator delete[](void* p, std::align_val_t) noexcept { uncounted(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { uncounted(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { uncounted(p); }

namespace afr {
namespace {

// Counts samples and throws them away, so that the samples are not what grows.
class DiscardingSink : public SampleSink {
 public:
  void on_batch(SampleBatch&& batch) override { samples += batch.samples.size(); }
  void on_tiling(TilingSnapshot&&) override {}
  uint64_t samples = 0;
};

// The most heap a sampler of `region` in a width x height image takes while it is built,
// fills and runs 3000 steps (the scene and tracer are built before counting starts).
int64_t peak_heap(const Scene& scene, int32_t width, int32_t height, PixelRect region, int b) {
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  DiscardingSink sink;
  SamplerConfig config;
  config.width = width;
  config.height = height;
  config.region = region;
  config.b = b;
  config.seed = 7;
  config.fill_step = 8;
  const int64_t before = g_live.load();
  g_peak = before;
  {
    Sampler sampler(scene, tracer, clock, config, sink);
    sampler.fill();
    for (int k = 0; k < 3000; ++k) sampler.step();
    sampler.flush();
    EXPECT_GT(sink.samples, 3000u);
  }
  return g_peak.load() - before;
}

// A deep buffer slot holds 32 bytes of statistics and 84 of what reprojection reads (96 where
// something moves); per pixel b slots and a 2-byte queue. The cells' sums (88 bytes per cell
// of at least 16 pixels) and the tiles come on top: the budget below allows 12 bytes per pixel
// and 1 MiB for them, the sample batch and the tiling.
constexpr int64_t kFixedBudget = int64_t(1) << 20;
int64_t budget(int64_t pixels, int b, bool moving) {
  return pixels * (b * (32 + 84 + (moving ? 12 : 0)) + 2 + 12) + kFixedBudget;
}

TEST(SamplerMemoryTest, SmallRegionOfAGigapixelImageTakesHeapForTheRegionOnly) {
  // 256 x 128 pixels of a 32768 x 32768 image: one byte per image pixel would be 1 GiB.
  const Scene scene = testing::edge_scene();
  const PixelRect region{16000, 16000, 16256, 16128};
  for (int b : {1, 4}) {
    SCOPED_TRACE(b);
    const int64_t huge = peak_heap(scene, 32768, 32768, region, b);
    EXPECT_LE(huge, budget(region.area(), b, scene.has_moving_geometry()));
    // The same region's pixels in an image of their own size take the same heap, but for the
    // tiles, which follow what the image shows (a few thousand of 120 bytes).
    const int64_t own =
        peak_heap(scene, 256, 128, PixelRect{0, 0, region.width(), region.height()}, b);
    EXPECT_NEAR(double(huge), double(own), 1024.0 * 1024.0);
  }
}

TEST(SamplerMemoryTest, HeapPerRegionPixelStaysInItsBudgetAsTheRegionGrows) {
  // Three times the pixels, three times the per-pixel part: the slope between the two is per region
  // pixel, whatever the fixed part, and the moving scene keeps velocities as well.
  const Scene scene = testing::moving_scene();
  ASSERT_TRUE(scene.has_moving_geometry());
  for (int b : {1, 4}) {
    SCOPED_TRACE(b);
    const int64_t small = peak_heap(scene, 1024, 1024, PixelRect{0, 0, 256, 256}, b);
    const int64_t large = peak_heap(scene, 1024, 1024, PixelRect{0, 0, 768, 256}, b);
    const double per_pixel = double(large - small) / (512.0 * 256.0);
    EXPECT_LE(per_pixel, double(b * (32 + 84 + 12) + 2 + 12));
    // At least the slots themselves: what is measured is the buffer, not a stray allocation.
    EXPECT_GE(per_pixel, double(b * (32 + 84 + 12) + 2));
  }
}

}  // namespace
}  // namespace afr
