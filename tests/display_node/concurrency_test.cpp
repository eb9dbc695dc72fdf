// Ingest on one thread while another reconstructs: the race test of the reconstructor (run it
// under ThreadSanitizer), and a check that nothing ingested concurrently is lost or torn.
#include <afr/display/cpu_reconstructor.h>

#include <afr/common/random.h>

#include "test_support.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace afr {
namespace {

TEST(ConcurrencyTest, IngestWhileReconstructingLosesNothing) {
  const int W = 64, H = 48;
  ReconstructorConfig cfg;
  cfg.image.width = W;
  cfg.image.height = H;
  cfg.capacity = 20000;
  cfg.threads = 2;
  // One splat size whatever the coverage map says: the image then depends only on the samples
  // in the store and the last tiling, not on the images before, so it can be compared with a
  // reference.
  cfg.splat.min_radius = 3.0f;
  cfg.splat.max_radius = 3.0f;
  std::vector<SampleBatch> batches;
  Pcg32 rng(31);
  for (int i = 0; i < 120; ++i) {
    batches.push_back(test::random_batch(rng, 500, W, H, 0.01 * i, 0.01 * (i + 1), 1 + i % 3));
  }
  const Camera camera;
  const double now = 1.2;

  CpuReconstructor live(cfg);
  std::atomic<bool> done{false};
  std::thread ingest([&] {
    for (size_t i = 0; i < batches.size(); ++i) {
      live.add_batch(batches[i]);
      std::this_thread::yield();  // interleave with the reconstructions
      if (i % 10 == 0) {
        live.set_tiling(test::uniform_tiling(W, H, 0.05f, 0.05f, 0.2f, 50.0f, 0.01 * double(i)));
      }
    }
    done = true;
  });
  int images = 0;
  Image image;
  while (!done || images < 3) {
    live.reconstruct(camera, now, W, H, &image);
    ASSERT_TRUE(test::all_finite(image));
    ASSERT_LE(live.frame_stats().stored, cfg.capacity);
    ++images;
  }
  ingest.join();
  live.reconstruct(camera, now, W, H, &image);
  EXPECT_EQ(live.ingest_stats().accepted, 120u * 500u);
  EXPECT_EQ(live.frame_stats().stored, cfg.capacity);

  // The same inputs, one after the other, on one thread.
  CpuReconstructor reference(cfg);
  for (const SampleBatch& b : batches) reference.add_batch(b);
  reference.set_tiling(test::uniform_tiling(W, H, 0.05f, 0.05f, 0.2f, 50.0f, 1.1));
  const Image want = reference.reconstruct(camera, now, W, H);
  EXPECT_EQ(image.pixels, want.pixels);
}

}  // namespace
}  // namespace afr
