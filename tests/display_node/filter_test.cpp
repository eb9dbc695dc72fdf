#include "support/numbers.h"

#include <afr/display/filter.h>

#include <afr/common/error.h>
#include <afr/common/random.h>
#include <afr/display/fast_exp.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace afr {
namespace {

using afr::testing::kInf;
using afr::testing::kNaN;

void expect_in_range(const FilterExtents& e, const FilterLimits& l) {
  EXPECT_TRUE(std::isfinite(e.e_x) && std::isfinite(e.e_y) && std::isfinite(e.e_t));
  EXPECT_GE(e.e_x, l.min_spatial_extent);
  EXPECT_LE(e.e_x, l.max_spatial_extent);
  EXPECT_GE(e.e_y, l.min_spatial_extent);
  EXPECT_LE(e.e_y, l.max_spatial_extent);
  EXPECT_GE(e.e_t, l.min_temporal_extent);
  EXPECT_LE(e.e_t, l.max_temporal_extent);
}

TEST(FilterTest, UnclampedExtentsAreThePapersCubeRoots) {
  const FilterLimits limits;
  const double G_x = 0.05, G_y = 0.1, G_t = 0.5, R_l = 10.0, V_s = 1.0 / R_l;
  const FilterExtents e =
      filter_extents(float(G_x), float(G_y), float(G_t), float(R_l), 10.0f, limits);
  // By hand: e_x = cbrt(0.1 * 0.1 * 0.5 / 0.05^2) = cbrt(2), e_y = cbrt(0.25), e_t = cbrt(0.002).
  EXPECT_NEAR(e.e_x, std::cbrt(2.0), 1e-5);
  EXPECT_NEAR(e.e_y, std::cbrt(0.25), 1e-5);
  EXPECT_NEAR(e.e_t, std::cbrt(0.002), 1e-6);
  // Equal expected color change in every dimension, volume V_s.
  EXPECT_NEAR(e.e_x * G_x, e.e_y * G_y, 1e-6);
  EXPECT_NEAR(e.e_x * G_x, e.e_t * G_t, 1e-6);
  EXPECT_NEAR(double(e.e_x) * e.e_y * e.e_t, V_s, 1e-6);
}

TEST(FilterTest, StaticRegionReachesBackAsFarAsTheStoreAndSharpensInSpace) {
  // No temporal change: the filter would reach back forever; the store's depth caps it and the
  // volume V_s goes to space: e_x e_y = V_s / depth, here with e_x = e_y.
  const FilterLimits limits;
  const float R_l = 6.0f, depth = 0.65f;
  const FilterExtents e = filter_extents(0.02f, 0.02f, 0.0f, R_l, depth, limits);
  EXPECT_FLOAT_EQ(e.e_t, depth);
  EXPECT_NEAR(e.e_x, std::sqrt(1.0 / (R_l * depth)), 1e-5);
  EXPECT_NEAR(e.e_y, e.e_x, 1e-6);
  // With twice the gradient along y, the filter is half as wide along y (same area).
  const FilterExtents f = filter_extents(0.02f, 0.04f, 0.0f, R_l, depth, limits);
  EXPECT_NEAR(f.e_x / f.e_y, 2.0, 1e-5);
  EXPECT_NEAR(double(f.e_x) * f.e_y, 1.0 / (R_l * depth), 1e-5);
}

TEST(FilterTest, SpatialClampKeepsTheVolumeInTime) {
  // Strong temporal change and a flat image: the spatial extents hit their maximum and the
  // temporal extent is what keeps the volume.
  FilterLimits limits;
  const FilterExtents e = filter_extents(0.0f, 0.0f, 50.0f, 1.0f, 10.0f, limits);
  EXPECT_FLOAT_EQ(e.e_x, limits.max_spatial_extent);
  EXPECT_FLOAT_EQ(e.e_y, limits.max_spatial_extent);
  EXPECT_NEAR(e.e_t, 1.0 / (double(limits.max_spatial_extent) * double(limits.max_spatial_extent)),
              1e-7);
  // An edge along y (change only across x): narrow in x, wide in y, but at most
  // max_anisotropy times wider; without that cap, as wide as the clamp allows.
  const FilterExtents g = filter_extents(1.0f, 0.0f, 0.1f, 4.0f, 10.0f, limits);
  EXPECT_FLOAT_EQ(g.e_x, limits.min_spatial_extent);
  EXPECT_GT(g.e_y, g.e_x);
  EXPECT_LE(g.e_y, limits.max_anisotropy * g.e_x * 1.0001f);
  FilterLimits uncapped = limits;
  uncapped.max_anisotropy = kInf;
  const FilterExtents h = filter_extents(1.0f, 0.0f, 0.1f, 4.0f, 10.0f, uncapped);
  EXPECT_FLOAT_EQ(h.e_x, limits.min_spatial_extent);
  EXPECT_FLOAT_EQ(h.e_y, limits.max_spatial_extent);
}

TEST(FilterTest, StaticEdgeReachesBackTheWholeDepth) {
  // A still horizontal edge: G_x = 0 (no change along it), G_t = 0. Measured in the static
  // test scene: with the floors of G_x and G_t taken as gradients (1e-4 lum/px against 1e-4
  // lum/s), the cube roots traded pixels for seconds one to one and gave e_x = 2.3 px, e_t =
  // 11 ms of a 0.65 s store: the edge was rebuilt from ~2% of its samples, blurred 2.3 px
  // along itself. No temporal change means the whole depth; the volume then goes to space.
  const FilterLimits limits;
  const float R_l = 131.0f, depth = 0.645f;
  const FilterExtents e = filter_extents(0.0f, 0.15f, 0.0f, R_l, depth, limits);
  EXPECT_FLOAT_EQ(e.e_t, depth);
  EXPECT_FLOAT_EQ(e.e_x, limits.min_spatial_extent);  // 1 / (R_l depth) = 0.012 px^2
  EXPECT_FLOAT_EQ(e.e_y, limits.min_spatial_extent);
  // Sparser, the same edge: e_x e_y = 1 / (R_l depth), 4 times longer along the edge.
  const FilterExtents f = filter_extents(0.0f, 0.15f, 0.0f, 0.5f, depth, limits);
  EXPECT_FLOAT_EQ(f.e_t, depth);
  EXPECT_NEAR(f.e_x / f.e_y, limits.max_anisotropy, 1e-4);
  EXPECT_NEAR(double(f.e_x) * f.e_y, 1.0 / (0.5 * depth), 1e-4);
}

TEST(FilterTest, DegenerateInputsGiveFiniteExtentsInTheirRanges) {
  const FilterLimits limits;
  const float values[] = {0.0f, -1.0f, kNaN, kInf, -kInf, 1e-30f, 1e30f, 0.3f};
  for (float gx : values) {
    for (float gt : values) {
      for (float rate : values) {
        for (float depth : values) {
          expect_in_range(filter_extents(gx, 0.1f, gt, rate, depth, limits), limits);
          expect_in_range(filter_extents(0.1f, gx, gt, rate, depth, limits), limits);
        }
      }
    }
  }
  // Zero gradients and zero rate: the widest filter in space, reaching back the whole depth.
  const FilterExtents e = filter_extents(0.0f, 0.0f, 0.0f, 0.0f, 2.0f, limits);
  EXPECT_FLOAT_EQ(e.e_t, 2.0f);
  EXPECT_FLOAT_EQ(e.e_x, limits.max_spatial_extent);
}

TEST(FilterTest, RandomInputsStayInRange) {
  const FilterLimits limits;
  Pcg32 rng(7);
  for (int i = 0; i < 100000; ++i) {
    const auto r = [&] { return std::exp2(80.0f * rng.next_float() - 40.0f); };
    expect_in_range(filter_extents(r(), r(), r(), r(), r(), limits), limits);
  }
}

TEST(FilterTest, TileFilterScalesToOutputPixels) {
  const TileFilter f = make_tile_filter(FilterExtents{1.5f, 0.5f, 0.25f}, 2.0f, 3.0f);
  EXPECT_FLOAT_EQ(f.sigma_x, 3.0f);
  EXPECT_FLOAT_EQ(f.sigma_y, 1.5f);
  EXPECT_FLOAT_EQ(f.e_t, 0.25f);
  EXPECT_FLOAT_EQ(f.k_t, 0.5f / 0.0625f);
}

TEST(FilterTest, ModesParseByName) {
  for (ReconstructionMode m :
       {ReconstructionMode::kAdaptive, ReconstructionMode::kTraditionalFrameless,
        ReconstructionMode::kAdaptiveNoReprojection}) {
    EXPECT_EQ(parse_mode(mode_name(m)), m);
  }
  EXPECT_THROW(parse_mode("gaussian"), Error);
}

TEST(FastExpTest, MatchesStdExpToTwoTenthsOfAMillionth) {
  double worst = 0.0;
  for (int i = 0; i < 2000000; ++i) {  // (-87, 0]
    const float x = -87.0f * float(i) / 2000000.0f;
    const double exact = std::exp(double(x));
    worst = std::max(worst, std::abs(double(fast_exp(x)) - exact) / exact);
  }
  EXPECT_LT(worst, 3e-7);
  EXPECT_EQ(fast_exp(0.0f), 1.0f);
  EXPECT_EQ(fast_exp(3.0f), 1.0f);  // positive arguments are taken as 0
  EXPECT_EQ(fast_exp(-88.0f), 0.0f);
  EXPECT_EQ(fast_exp(-kInf), 0.0f);
  EXPECT_EQ(fast_exp(kNaN), 0.0f);
}

#if defined(__SSE2__)
TEST(FastExpTest, FourLanesAreBitForBitTheScalarOne) {
  Pcg32 rng(8);
  for (int i = 0; i < 100000; ++i) {
    alignas(16) float x[4], y[4];
    for (float& v : x) v = -100.0f * rng.next_float() + (rng.next_below(50) == 0 ? 120.0f : 0.0f);
    if (i == 0) x[1] = kNaN, x[2] = -kInf, x[3] = -87.0f;
    _mm_store_ps(y, fast_exp4(_mm_load_ps(x)));
    for (int k = 0; k < 4; ++k) ASSERT_EQ(y[k], fast_exp(x[k])) << x[k];
  }
}
#endif

}  // namespace
}  // namespace afr
