// The sampler's heap follows the region it owns, never the image: measured by counting every
// byte this program allocates (operator new is replaced here, which is why these tests are a
// binary of their own), not by what the sampler says it holds.
#include <afr/sampler/sampler.h>
#include <afr/sampler/sampler_pool.h>

#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
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

struct Heap {
  int64_t peak = 0;           // the most heap the sampler took, bytes
  int64_t pooled_pixels = 0;  // pixels the deep buffer gave the rest of crosshairs to
  int64_t rest_bytes = 0;     // bytes of that rest per crosshair slot
};

// The most heap a sampler of `region` in a width x height image takes while it is built,
// fills (one crosshair every fill_step pixels) and runs `steps` steps; the scene and the tracer
// are built before counting starts.
Heap peak_heap(const Scene& scene, int32_t width, int32_t height, PixelRect region, int b,
               int fill_step, int steps) {
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  DiscardingSink sink;
  SamplerConfig config;
  config.image.width = width;
  config.image.height = height;
  config.region = region;
  config.b = b;
  config.seed = 7;
  config.fill_step = fill_step;
  const int64_t before = g_live.load();
  g_peak = before;
  Heap heap;
  {
    Sampler sampler(scene, tracer, clock, config, sink);
    sampler.fill();
    for (int k = 0; k < steps; ++k) sampler.step();
    sampler.flush();
    EXPECT_GT(sink.samples, uint64_t(steps));
    heap.pooled_pixels = sampler.buffer().pooled_pixels();
    heap.rest_bytes = int64_t(sampler.buffer().rest_bytes());
  }
  heap.peak = g_peak.load() - before;
  return heap;
}

// Every pixel of the region takes b x 32 bytes of crosshair statistics, a 2-byte queue and a
// 4-byte index into the pool of the rest; the cells' sums (88 bytes per cell of at least 16
// pixels) come on top: 12 bytes per pixel are allowed for them. A pixel holding crosshairs
// takes b x the rest (84 bytes, 96 where something moves) from a pool that grows 4096 such
// pixels at a time.
int64_t per_pixel_budget(int b) { return b * 32 + 2 + 4 + 12; }
constexpr int64_t kPoolStep = 4096;
// The tiles, the sample batch and the tiling's other arrays.
constexpr int64_t kFixedBudget = int64_t(1) << 20;

TEST(SamplerMemoryTest, SmallRegionOfAGigapixelImageTakesHeapForTheRegionOnly) {
  // 256 x 128 pixels of a 32768 x 32768 image: one byte per image pixel would be 1 GiB.
  const Scene scene = testing::edge_scene();
  const PixelRect region{16000, 16000, 16256, 16128};
  for (int b : {1, 4}) {
    SCOPED_TRACE(b);
    const Heap huge = peak_heap(scene, 32768, 32768, region, b, 8, 3000);
    ASSERT_GT(huge.pooled_pixels, 0);
    ASSERT_LE(huge.pooled_pixels, region.area());
    EXPECT_LE(huge.peak, region.area() * per_pixel_budget(b) +
                             (huge.pooled_pixels + kPoolStep) * b * huge.rest_bytes + kFixedBudget);
    // The same region's pixels in an image of their own size take about the same heap: the
    // tiles and the pixels that hold crosshairs follow what the image shows.
    const Heap own =
        peak_heap(scene, 256, 128, PixelRect{0, 0, region.width(), region.height()}, b, 8, 3000);
    EXPECT_NEAR(double(huge.peak), double(own.peak),
                double(kFixedBudget + 2 * kPoolStep * b * huge.rest_bytes));
  }
}

TEST(SamplerMemoryTest, HeapPerRegionPixelFollowsThePixelsThatHoldCrosshairs) {
  // Three times the pixels, three times the per-pixel part: the slope between two regions is
  // per region pixel, whatever the fixed part. A moving scene keeps velocities as well (84 + 12
  // bytes a slot; the points' spaces, 20 more, only with CrosshairMotion::kTransform).
  const Scene scene = testing::moving_scene();
  ASSERT_TRUE(scene.has_moving_geometry());
  const PixelRect small{0, 0, 256, 256}, large{0, 0, 768, 256};
  const double added = double(large.area() - small.area());
  for (int b : {1, 4}) {
    SCOPED_TRACE(b);
    // A crosshair in every pixel: every pixel takes its rest.
    const Heap full_small = peak_heap(scene, 1024, 1024, small, b, 1, 0);
    const Heap full_large = peak_heap(scene, 1024, 1024, large, b, 1, 0);
    ASSERT_EQ(full_large.pooled_pixels, large.area());
    ASSERT_EQ(full_large.rest_bytes, 96);
    const double full = double(full_large.peak - full_small.peak) / added;
    EXPECT_LE(full, double(per_pixel_budget(b) + b * 96));
    EXPECT_GE(full, double(b * (32 + 96) + 2 + 4));  // at least the slots themselves
    // One pixel in 64 holds a crosshair: the others take the statistics part only.
    const Heap sparse_small = peak_heap(scene, 1024, 1024, small, b, 8, 0);
    const Heap sparse_large = peak_heap(scene, 1024, 1024, large, b, 8, 0);
    const double sparse = double(sparse_large.peak - sparse_small.peak) / added;
    EXPECT_LE(sparse, double(per_pixel_budget(b)) + b * 96 / 8.0);
    EXPECT_GE(sparse, double(b * 32 + 2 + 4));
    // The figures docs/sampler.md quotes.
    std::printf(
        "b = %d: %.1f B per region pixel with a crosshair in every pixel, %.1f B with one "
        "in 64\n",
        b, full, sparse);
  }
}

// The threads of a sampler pool share one build of the scene (Tracer::ShareGeometry), and the
// tracers hold the pool's scene rather than a copy of it: a pool of 4 threads takes little more
// heap than a pool of 1, and neither copies the scene. A scene of a 2-million-triangle static
// mesh (48 MB of positions, normals and indices) in a small image; the pools built, not
// started. What they take is the tracer's world-space vertices (24 MB). (Embree's BVHs,
// allocated outside operator new, are shared the same way; bench/pool_memory.py measures a
// sampler process's resident memory.)
TEST(SamplerMemoryTest, PoolThreadsShareTheScenesGeometry) {
  Scene scene = testing::edge_scene();
  Primitive grid;
  const int n = 1000;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i)
      grid.positions.emplace_back(float(i) / n - 0.5f, float(j) / n - 0.5f, -3.0f);
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      grid.indices.insert(grid.indices.end(), {a, b, c, b, d, c});
    }
  }
  grid.material = 0;
  Mesh mesh;
  mesh.primitives.push_back(std::move(grid));
  scene.meshes.push_back(std::move(mesh));
  Node node;
  node.mesh = int(scene.meshes.size()) - 1;
  scene.nodes.push_back(node);
  scene.roots.push_back(int(scene.nodes.size()) - 1);
  scene.finalize();
  VirtualClock clock(1e5);
  DiscardingSink sink;
  SamplerConfig config;
  config.image.width = 64;
  config.image.height = 64;
  config.region = PixelRect{0, 0, 64, 64};
  config.seed = 7;
  auto heap_of_pool = [&](int threads) {
    SamplerPoolOptions options;
    options.threads = threads;
    const int64_t before = g_live.load();
    SamplerPool pool(scene, config, options, clock, sink);
    return g_live.load() - before;
  };
  const Primitive& p = scene.meshes.back().primitives[0];
  const int64_t scene_bytes =
      int64_t(p.positions.size() * sizeof(glm::vec3) + p.normals.size() * sizeof(glm::vec3) +
              p.indices.size() * sizeof(uint32_t));
  const int64_t one = heap_of_pool(1), four = heap_of_pool(4);
  std::printf("scene %.1f MB; pool heap: %.1f MB with 1 thread, %.1f MB with 4\n",
              double(scene_bytes) / 1e6, double(one) / 1e6, double(four) / 1e6);
  const int64_t world_vertices = int64_t(p.positions.size() * 2 * sizeof(glm::vec3));
  EXPECT_GE(one, world_vertices);  // the static geometry in world space
  EXPECT_LT(one, scene_bytes);     // and no copy of the scene
  EXPECT_LT(double(four), 1.2 * double(one));
}

}  // namespace
}  // namespace afr
