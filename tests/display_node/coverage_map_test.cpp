#include <afr/display/coverage_map.h>

#include <gtest/gtest.h>

#include <limits>

namespace afr {
namespace {

TEST(CoverageMapTest, SplatRadiusFollowsSection62) {
  // The map holds growths (radius over filter radius); a splat takes the rule's growth times
  // its own filter radius.
  const SplatSizeRule rule;
  EXPECT_FLOAT_EQ(splat_radius(nullptr, 2.5f, rule), 2.5f);  // no previous image
  CoverageCell hole{0.0f, 0.0f};
  EXPECT_FLOAT_EQ(splat_radius(&hole, 2.5f, rule), 10.0f);
  CoverageCell sparse{2.0f, 3.0f};  // mean growth 1.5
  EXPECT_FLOAT_EQ(splat_radius(&sparse, 2.0f, rule), 12.0f);
  CoverageCell dense{40.0f, 80.0f};  // mean 2
  EXPECT_FLOAT_EQ(splat_radius(&dense, 3.0f, rule), 4.2f);
  CoverageCell fine{10.0f, 25.0f};  // mean 2.5
  EXPECT_FLOAT_EQ(splat_radius(&fine, 2.0f, rule), 5.0f);
  // The thresholds themselves are not under- or oversampled.
  CoverageCell four{4.0f, 8.0f}, thirty_two{32.0f, 64.0f};
  EXPECT_FLOAT_EQ(splat_radius(&four, 1.5f, rule), 3.0f);
  EXPECT_FLOAT_EQ(splat_radius(&thirty_two, 1.5f, rule), 3.0f);
  EXPECT_FLOAT_EQ(splat_growth(6.0f, 2.0f), 3.0f);
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
  CoverageCell sparse{1.0f, 20.0f};
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

}  // namespace
}  // namespace afr
