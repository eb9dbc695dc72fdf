// Framed rendering with temporal accumulation (taa.h): a uniform neighbourhood resolves to its
// color, and on a still scene the jittered frames accumulate into more detail than one frame's
// upsampled grid holds.
#include <afr/common/image.h>
#include <afr/eval/taa.h>

#include "eval_test_scenes.h"

#include <gtest/gtest.h>

#include <cmath>

namespace afr::eval {
namespace {

constexpr int kW = 64, kH = 64, kGrid = 16;

double rms(const Image& a, const Image& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const glm::vec3 d = a.pixels[i] - b.pixels[i];
    sum += double(glm::dot(d, d)) / 3.0;
  }
  return std::sqrt(sum / double(a.pixels.size()));
}

TEST(TaaTest, AccumulatesDetailOnAStillSceneAndKeepsUniformRegionsExact) {
  const Scene scene = testing::sliding_quad_scene(0.0);  // the quad stands still
  Tracer tracer(scene);
  const Image reference = testing::reference_frame(tracer, 1.0, kW, kH);
  TemporalAccumulator taa(kW, kH, kGrid, kGrid, TaaOptions{});
  TraceStats stats;
  double first = 0.0, last = 0.0;
  Image image;
  for (int k = 0; k < 32; ++k) {
    image = taa.render(tracer, k, 1.0 + k / 60.0, 2, &stats);
    if (k == 0) first = rms(image, reference);
    last = rms(image, reference);
    for (const glm::vec3& c : image.pixels) {
      ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z)) << k;
    }
  }
  EXPECT_EQ(stats.primary_rays, uint64_t(32 * kGrid * kGrid));
  // The quad's edges, blurred over a grid cell in frame 0, sharpen as jittered frames add up.
  EXPECT_LT(last, 0.7 * first) << "frame 0: " << first << ", frame 31: " << last;
  // Far from the edges every neighbour has one color: white inside the quad, black outside.
  tracer.set_time(1.0);
  int inside = 0, outside = 0;
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      bool uniform = true;  // the reference is one color over this pixel's 13 x 13 surroundings
      for (int dy = -6; dy <= 6 && uniform; ++dy) {
        for (int dx = -6; dx <= 6 && uniform; ++dx) {
          const int xx = std::clamp(x + dx, 0, kW - 1), yy = std::clamp(y + dy, 0, kH - 1);
          uniform = reference.at(xx, yy) == reference.at(x, y);
        }
      }
      if (!uniform) continue;
      const glm::vec3 want = reference.at(x, y);
      (want.x > 0.5f ? inside : outside) += 1;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(image.at(x, y)[c], want[c], 1e-5f) << x << "," << y;
    }
  }
  EXPECT_GT(inside, 0);
  EXPECT_GT(outside, 0);
}

}  // namespace
}  // namespace afr::eval
