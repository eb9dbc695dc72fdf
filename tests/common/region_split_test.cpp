#include <afr/common/region_split.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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

// ---- Cutting by mass

// The reference: the same adds, spread per pixel, and each cell's pixels averaged (the density
// is constant per cell). Cells of 8 x 8 pixels here, so the average is over whole pixels.
TEST(MassDensityTest, MassIsTheCellAveragedSumOverAnyRectangle) {
  constexpr int W = 96, H = 64, kCell = 8;
  MassDensity d(W, H, W / kCell, H / kCell);
  std::vector<double> px(W * H, 0.0);
  Pcg32 rng(5);
  double added = 0.0;
  for (int k = 0; k < 40; ++k) {
    const int x0 = int(rng.next_below(W)), y0 = int(rng.next_below(H));
    const PixelRect r{x0, y0, x0 + 1 + int(rng.next_below(W - x0)),
                      y0 + 1 + int(rng.next_below(H - y0))};
    const double m = 10.0 * rng.next_double();
    d.add(r, m);
    added += m;
    for (int y = r.y0; y < r.y1; ++y) {
      for (int x = r.x0; x < r.x1; ++x) px[y * W + x] += m / double(r.area());
    }
  }
  d.add(PixelRect{0, 0, W, H}, std::nan(""));  // ignored
  d.add(PixelRect{0, 0, W, H}, -1.0);          // ignored
  EXPECT_NEAR(d.total(), added, 1e-9 * added);
  std::vector<double> cell_avg(W * H, 0.0);
  for (int cy = 0; cy < H / kCell; ++cy) {
    for (int cx = 0; cx < W / kCell; ++cx) {
      double sum = 0.0;
      for (int y = 0; y < kCell; ++y) {
        for (int x = 0; x < kCell; ++x) sum += px[(cy * kCell + y) * W + cx * kCell + x];
      }
      for (int y = 0; y < kCell; ++y) {
        for (int x = 0; x < kCell; ++x) cell_avg[(cy * kCell + y) * W + cx * kCell + x] = sum / 64;
      }
    }
  }
  for (int k = 0; k < 500; ++k) {
    const int x0 = int(rng.next_below(W)), y0 = int(rng.next_below(H));
    const PixelRect r{x0, y0, x0 + int(rng.next_below(W - x0 + 1)),
                      y0 + int(rng.next_below(H - y0 + 1))};
    double expected = 0.0;
    for (int y = r.y0; y < r.y1; ++y) {
      for (int x = r.x0; x < r.x1; ++x) expected += cell_avg[y * W + x];
    }
    EXPECT_NEAR(d.mass(r), expected, 1e-9 * added)
        << r.x0 << "," << r.y0 << " " << r.x1 << "," << r.y1;
  }
}

TEST(MassDensityTest, SplitByMassGivesEachPartItsShareOfTheMass) {
  // All the error in the left eighth of a 256 x 128 image, a floor elsewhere: two equal shares
  // cut it near the middle of that eighth, not at the middle of the image.
  MassDensity d(256, 128, 64, 32);
  d.add(PixelRect{0, 0, 32, 128}, 1000.0);
  d.add_uniform(1e-4);
  const std::vector<double> equal = {1.0, 1.0};
  const auto parts = split_region(PixelRect{0, 0, 256, 128}, equal, d);
  expect_partition(PixelRect{0, 0, 256, 128}, parts);
  EXPECT_NEAR(parts[0].x1, 16, 1);
  EXPECT_NEAR(d.mass(parts[0]), d.mass(parts[1]), 0.05 * d.total());
  // Random masses and shares: each part's mass within a column's (or row's) worth per cut
  // level of its share.
  Pcg32 rng(9);
  for (int run = 0; run < 30; ++run) {
    MassDensity m(200, 150, 50, 30);
    for (int k = 0; k < 20; ++k) {
      const int x0 = int(rng.next_below(200)), y0 = int(rng.next_below(150));
      m.add(PixelRect{x0, y0, std::min(200, x0 + 1 + int(rng.next_below(60))),
                      std::min(150, y0 + 1 + int(rng.next_below(60)))},
            rng.next_double());
    }
    m.add_uniform(1e-3 * m.total() / (200.0 * 150.0));
    const size_t n = 1 + rng.next_below(6);
    std::vector<double> shares(n);
    double total = 0.0;
    for (double& s : shares) total += (s = 0.2 + rng.next_double());
    const auto cut = split_region(PixelRect{0, 0, 200, 150}, shares, m);
    expect_partition(PixelRect{0, 0, 200, 150}, cut);
    double worst_line = 0.0;  // the heaviest single column or row
    for (int x = 0; x < 200; ++x) worst_line = std::max(worst_line, m.mass({x, 0, x + 1, 150}));
    for (int y = 0; y < 150; ++y) worst_line = std::max(worst_line, m.mass({0, y, 200, y + 1}));
    for (size_t k = 0; k < n; ++k) {
      EXPECT_NEAR(m.mass(cut[k]), m.total() * shares[k] / total, 3.0 * worst_line + 1e-9)
          << "run " << run << " part " << k;
      EXPECT_FALSE(cut[k].empty());
    }
  }
  // Blending: halfway between an error on the left and one on the right, equal halves.
  MassDensity l(64, 64, 8, 8), r(64, 64, 8, 8);
  l.add(PixelRect{0, 0, 8, 64}, 10.0);
  r.add(PixelRect{56, 0, 64, 64}, 10.0);
  l.blend(r, 0.5);
  EXPECT_NEAR(l.mass(PixelRect{0, 0, 32, 64}), 5.0, 1e-9);
  EXPECT_NEAR(l.mass(PixelRect{32, 0, 64, 64}), 5.0, 1e-9);
  // No mass at all: areas, as the plain split.
  MassDensity none(64, 64, 8, 8);
  EXPECT_EQ(split_region(PixelRect{0, 0, 64, 64}, equal, none),
            split_region(PixelRect{0, 0, 64, 64}, equal));
}

TEST(PixelRectTest, IntersectIsTheOverlapOrTheEmptyRectangle) {
  EXPECT_EQ(intersect(PixelRect{0, 0, 10, 8}, PixelRect{4, -3, 20, 5}), (PixelRect{4, 0, 10, 5}));
  EXPECT_EQ(intersect(PixelRect{4, -3, 20, 5}, PixelRect{0, 0, 10, 8}), (PixelRect{4, 0, 10, 5}));
  // Touching edges and disjoint rectangles: {} (not a rectangle with x1 < x0).
  EXPECT_EQ(intersect(PixelRect{0, 0, 10, 8}, PixelRect{10, 0, 12, 8}), PixelRect{});
  EXPECT_EQ(intersect(PixelRect{0, 0, 10, 8}, PixelRect{50, 60, 70, 80}), PixelRect{});
  EXPECT_EQ(intersect(PixelRect{0, 0, 10, 8}, PixelRect{}), PixelRect{});
}

}  // namespace
}  // namespace afr
