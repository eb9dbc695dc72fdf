#include <afr/display/coverage_map.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace afr {
namespace {

TEST(CoverageMapTest, SplatRadiusFollowsSection62) {
  // The map holds growths (radius over filter radius); a splat takes the rule's growth times
  // its own filter radius. b = m + relax (1 - m) for a mean growth m.
  const SplatSizeRule rule;
  const auto base = [&](float m) { return m + rule.relax * (1.0f - m); };
  EXPECT_FLOAT_EQ(splat_radius(nullptr, 2.5f, rule), 2.5f);  // no previous image
  CoverageCell hole{0.0f, 0.0f};
  EXPECT_FLOAT_EQ(splat_radius(&hole, 2.5f, rule), 10.0f);
  CoverageCell sparse{2.0f, 3.0f};  // mean growth 1.5; half the band's count: sqrt(2) larger
  EXPECT_FLOAT_EQ(splat_radius(&sparse, 2.0f, rule), 2.0f * base(1.5f) * std::sqrt(2.0f));
  CoverageCell very_sparse{0.125f, 0.125f};  // the factor is at most `grow`
  EXPECT_FLOAT_EQ(splat_radius(&very_sparse, 2.0f, rule), 2.0f * base(1.0f) * rule.grow);
  CoverageCell dense{40.0f, 80.0f};  // mean 2; half way (in log) to the band's count
  EXPECT_FLOAT_EQ(splat_radius(&dense, 3.0f, rule),
                  3.0f * base(2.0f) * std::sqrt(std::sqrt(32.0f / 40.0f)));
  CoverageCell very_dense{40000.0f, 40000.0f};  // the factor is at least `shrink`
  EXPECT_FLOAT_EQ(splat_radius(&very_dense, 12.0f, rule), 12.0f * base(1.0f) * rule.shrink);
  CoverageCell fine{10.0f, 25.0f};  // mean 2.5, in the band: only the pull toward 1
  EXPECT_FLOAT_EQ(splat_radius(&fine, 2.0f, rule), 2.0f * base(2.5f));
  // The factor is continuous: 1 at both ends of the band.
  CoverageCell four{4.0f, 8.0f}, thirty_two{32.0f, 64.0f};
  EXPECT_FLOAT_EQ(splat_radius(&four, 1.5f, rule), 1.5f * base(2.0f));
  EXPECT_FLOAT_EQ(splat_radius(&thirty_two, 1.5f, rule), 1.5f * base(2.0f));
  CoverageCell just_below{3.999f, 7.998f}, just_above{32.001f, 64.002f};
  EXPECT_NEAR(splat_radius(&just_below, 1.5f, rule), 1.5f * base(2.0f), 1e-3f);
  EXPECT_NEAR(splat_radius(&just_above, 1.5f, rule), 1.5f * base(2.0f), 1e-3f);
  EXPECT_FLOAT_EQ(splat_growth(6.0f, 2.0f), 3.0f);
}

// The former rule, the baseline afr-eval --coverage-rule thresholds compares with: hard
// factors at the band's ends, no pull toward 1, so a count one splat across an end moves the
// radius by 4x or 0.7x.
TEST(CoverageMapTest, TheThresholdsRuleMultipliesTheMeanGrowthAtTheBandsEnds) {
  SplatSizeRule rule;
  rule.thresholds = true;
  rule.shrink = 0.7f;
  EXPECT_FLOAT_EQ(splat_radius(nullptr, 2.5f, rule), 2.5f);
  CoverageCell hole{0.0f, 0.0f};
  EXPECT_FLOAT_EQ(splat_radius(&hole, 2.5f, rule), 10.0f);
  CoverageCell just_below{3.999f, 7.998f}, inside{4.0f, 8.0f}, just_above{32.001f, 64.002f};
  EXPECT_FLOAT_EQ(splat_radius(&just_below, 1.5f, rule), 1.5f * 2.0f * 4.0f);
  EXPECT_FLOAT_EQ(splat_radius(&inside, 1.5f, rule), 1.5f * 2.0f);
  EXPECT_FLOAT_EQ(splat_radius(&just_above, 1.5f, rule), 1.5f * 2.0f * 0.7f);
  CoverageCell huge{8.0f, 8000.0f};  // mean growth 1000: clamped to max_radius
  EXPECT_FLOAT_EQ(splat_radius(&huge, 1.5f, rule), rule.max_radius);
}

TEST(CoverageMapTest, GrowthConvergesToOneStateWhateverItStartsFrom) {
  // A pixel in a region of `density` samples per pixel, every splat of radius r = g r_f: it
  // is reached by about density x pi r^2 splats, each with growth g. Iterated image after
  // image from very different growths, the rule ends at one growth per density: 1 (the
  // filter's own size) where that size reaches a count in the band, else the growth that
  // brings the count to the nearer end of the band.
  const SplatSizeRule rule;
  const float r_f = 1.5f;
  for (const float density : {0.01f, 0.1f, 0.5f, 2.0f, 8.0f, 40.0f}) {
    SCOPED_TRACE(density);
    std::vector<float> ends;
    for (const float start : {0.3f, 1.0f, 3.0f, 15.0f}) {
      float r = start * r_f;
      for (int image = 0; image < 200; ++image) {
        const float count = std::max(1.0f, density * 3.14159265f * r * r);
        const CoverageCell cell{count, count * (r / r_f)};
        r = splat_radius(&cell, r_f, rule);
      }
      // Converged: one more image moves it by less than 0.1 %.
      const float count = std::max(1.0f, density * 3.14159265f * r * r);
      const CoverageCell cell{count, count * (r / r_f)};
      EXPECT_NEAR(splat_radius(&cell, r_f, rule), r, 1e-3f * r) << "from " << start;
      ends.push_back(r);
    }
    for (const float r : ends) EXPECT_NEAR(r, ends[0], 1e-3f * ends[0]);
    const float count = density * 3.14159265f * ends[0] * ends[0];
    const float count_at_filter_size = density * 3.14159265f * r_f * r_f;
    if (count_at_filter_size < rule.grow_below) {
      if (ends[0] < rule.max_radius) {  // grown until nearly enough samples reach
        EXPECT_GT(count, 0.8f * rule.grow_below);
        EXPECT_LT(count, rule.grow_below + 1e-3f);
      }
    } else if (count_at_filter_size > rule.shrink_above) {
      if (ends[0] > rule.min_radius) {  // shrunk nearly to the band
        EXPECT_GT(count, rule.shrink_above - 1e-3f);
        EXPECT_LT(count, 1.25f * rule.shrink_above);
      }
    } else {
      EXPECT_NEAR(ends[0], r_f, 0.01f * r_f);  // well sampled at the filter's size
    }
  }
}

TEST(CoverageMapTest, WideSplatsNextDoorDoNotWidenNarrowOnes) {
  // A cell reached by 30 splats grown 1x of narrow filters and by 2 of a wide sparse region's
  // filters (grown 1x too, radius 12): a narrow splat landing there stays narrow. With mean
  // radii it would take (30 x 1 + 2 x 12) / 32 = 1.7 pixels instead of 1.
  const SplatSizeRule rule;
  CoverageCell mixed{32.0f, 32.0f};
  EXPECT_FLOAT_EQ(splat_radius(&mixed, 1.0f, rule), 1.0f);
  EXPECT_FLOAT_EQ(splat_radius(&mixed, 12.0f, rule), 12.0f);
}

TEST(CoverageMapTest, SplatRadiusIsBounded) {
  const SplatSizeRule rule;
  CoverageCell sparse{1.0f, 40.0f};
  EXPECT_FLOAT_EQ(splat_radius(&sparse, 1.0f, rule), rule.max_radius);
  CoverageCell dense{1000.0f, 100.0f};
  EXPECT_FLOAT_EQ(splat_radius(&dense, 1.0f, rule), rule.min_radius);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FLOAT_EQ(splat_radius(nullptr, nan, rule), rule.min_radius);
  EXPECT_FLOAT_EQ(splat_radius(nullptr, std::numeric_limits<float>::infinity(), rule),
                  rule.max_radius);
}

TEST(CoverageMapTest, ResetDropsThePreviousImage) {
  CoverageMap map;
  map.reset(3, 2);
  EXPECT_EQ(map.at(1, 1), nullptr);
  map.cells()[4] = CoverageCell{5.0f, 7.0f};
  map.set_valid(true);
  ASSERT_NE(map.at(1, 1), nullptr);
  EXPECT_FLOAT_EQ(map.at(1, 1)->count, 5.0f);
  map.reset(3, 2);
  EXPECT_EQ(map.at(1, 1), nullptr);
  EXPECT_EQ(map.cells()[4].count, 0.0f);
}

// The widest splat a tile's density calls for: reached by at most 4 x shrink_above others.
TEST(CoverageMapTest, TheDensityCapKeepsTheExpectedCountAtFourTimesTheBand) {
  const SplatSizeRule rule;
  for (float density : {0.01f, 0.5f, 4.0f, 64.0f}) {
    const float r = splat_density_cap(density, rule);
    EXPECT_NEAR(density * (2.0f * r) * (2.0f * r), 4.0f * rule.shrink_above,
                1e-4f * rule.shrink_above);
  }
  EXPECT_FLOAT_EQ(splat_density_cap(4.0f, rule), std::sqrt(8.0f));
  // No stored sample, or garbage: no cap.
  for (float density : {0.0f, -1.0f, std::numeric_limits<float>::quiet_NaN()}) {
    EXPECT_EQ(splat_density_cap(density, rule), std::numeric_limits<float>::max());
  }
}

}  // namespace
}  // namespace afr
