// The reconstructor converges to one image for a given sample stream: the order in which
// batches arrive (which no network fixes) moves the image by rounding only, and that does not
// grow image after image (docs/reconstruction.md, "Coverage map"). Measured on the built-in
// scene at 256 x 256, 400K rays/s, 600 images, seeds 1-3 (afr-bench-stability --images 600
// --seeds 3): RMS 0.15-0.47 at image 600, at most 1.5 on the way (image 64, while the store
// first fills); the former thresholds (x4 below 4 splats, x0.7 above 32) reached 9-14.
#include <afr/common/builtin_scene.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "support/order_stability.h"
#include "support/timing.h"

namespace afr {
namespace {

TEST(ReconstructionStabilityTest, TwoArrivalOrdersEndWithinOneLevelOfEachOther) {
  // Smaller than the measurement above: 128 x 128 at the same rate, 300 images, time enough
  // for the thresholds' divergence, which showed by image 64. Measured for seeds 1-3: RMS
  // 0.33-0.45 at image 300, 0.34 on average over images 151-300 (seed 1). Single images
  // reach 2.4 during the camera's fast turn (images 282-286) and settle within a few images:
  // there the two stores hold different samples (the ring drops the oldest by arrival, and
  // the arrival order differs), and fast motion makes that visible.
  testing::StabilitySettings s;
  s.size = ImageExtent{128, 128};
  s.images = 300;
  const Scene scene = make_builtin_scene();
  // The end: the median of the last 30 images, which a fast turn of a few images (its timing
  // moves with the sample stream, that is with the processor) cannot decide alone.
  std::vector<double> rms;
  double late_sum = 0.0;
  int late = 0;
  testing::run_stability(scene, s, [&](int j, double, const Image& a, const Image& b) {
    rms.push_back(rms_error_255(a, b));
    if (j > s.images / 2) {
      late_sum += rms.back();
      ++late;
    }
  });
  std::vector<double> end(rms.end() - 30, rms.end());
  std::nth_element(end.begin(), end.begin() + 15, end.end());
  EXPECT_LT(end[15], 1.0);
  EXPECT_LT(late_sum / late, 1.0);
}

}  // namespace
}  // namespace afr
