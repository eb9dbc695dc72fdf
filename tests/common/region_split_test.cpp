#include <afr/common/region_split.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <vector>

namespace afr {
namespace {

void expect_partition(const PixelRect& region, const std::vector<PixelRect>& parts) {
  std::vector<int> cover(size_t(region.area()), 0);
  for (const PixelRect& p : parts) {
    for (int32_t y = p.y0; y < p.y1; ++y) {
      for (int32_t x = p.x0; x < p.x1; ++x) {
        ASSERT_TRUE(region.contains(x, y));
        ++cover[size_t(y - region.y0) * region.width() + (x - region.x0)];
      }
    }
  }
  for (int c : cover) ASSERT_EQ(c, 1);
}

TEST(RegionSplitTest, EqualSharesGiveEqualHalves) {
  const std::vector<double> shares = {1.0, 1.0};
  const auto parts = split_region(PixelRect{0, 0, 256, 128}, shares);
  EXPECT_EQ(parts[0], (PixelRect{0, 0, 128, 128}));
  EXPECT_EQ(parts[1], (PixelRect{128, 0, 256, 128}));
}

TEST(RegionSplitTest, AreasFollowSharesAndPartitionTheRegion) {
  Pcg32 rng(3);
  for (int run = 0; run < 50; ++run) {
    const size_t n = 1 + rng.next_below(7);
    std::vector<double> shares(n);
    double total = 0.0;
    for (double& s : shares) total += (s = 0.2 + rng.next_double());
    const PixelRect region{5, 9, 5 + 40 + int32_t(rng.next_below(200)),
                           9 + 40 + int32_t(rng.next_below(200))};
    const auto parts = split_region(region, shares);
    ASSERT_EQ(parts.size(), n);
    expect_partition(region, parts);
    for (size_t k = 0; k < n; ++k) {
      const double expected = region.area() * shares[k] / total;
      // Rounding the cuts to whole pixels moves at most a row or column per level.
      EXPECT_NEAR(double(parts[k].area()), expected, 0.1 * expected + 3.0 * 250.0);
      EXPECT_FALSE(parts[k].empty());
    }
  }
}

TEST(RegionSplitTest, TinyRegionsStillPartition) {
  const std::vector<double> shares = {1.0, 100.0, 1.0};
  const auto parts = split_region(PixelRect{0, 0, 3, 1}, shares);
  expect_partition(PixelRect{0, 0, 3, 1}, parts);
  for (const PixelRect& p : parts) EXPECT_EQ(p.area(), 1);
}

}  // namespace
}  // namespace afr
