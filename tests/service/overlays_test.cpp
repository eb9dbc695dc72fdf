#include <afr/display/service/overlays.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr::service {
namespace {

TilingSnapshot snapshot(uint32_t id, std::vector<TileInfo> tiles) {
  TilingSnapshot s;
  s.sampler_id = id;
  s.region = PixelRect{0, 0, 8, 4};
  s.tiles = std::move(tiles);
  return s;
}

TileInfo tile(PixelRect r, float gx, float gy, float gt) {
  TileInfo t;
  t.rect = r;
  t.G_x = gx;
  t.G_y = gy;
  t.G_t = gt;
  return t;
}

TEST(OverlaysTest, GradientOverlayIsFigure4ScaledPerChannel) {
  std::map<uint32_t, TilingSnapshot> tilings;
  tilings[1] = snapshot(1, {tile({0, 0, 4, 4}, 0.5f, 0.0f, 2.0f)});
  tilings[2] = snapshot(2, {tile({4, 0, 8, 2}, 1.0f, 0.25f, NAN)});
  const Image g = gradient_overlay(tilings, 8, 4);
  EXPECT_EQ(g.at(1, 1), glm::vec3(0.5f, 0.0f, 1.0f));
  EXPECT_EQ(g.at(6, 1), glm::vec3(1.0f, 1.0f, 0.0f));  // NaN shows as 0
  EXPECT_EQ(g.at(6, 3), glm::vec3(0.0f));              // no tile
}

// One steep tile must not darken all the others (the overlay looked black): the scale is the
// value that 95% of the tiled area lies at or below, and steeper tiles saturate.
TEST(OverlaysTest, GradientOverlaySaturatesTheSteepestTilesInsteadOfDarkeningTheRest) {
  std::map<uint32_t, TilingSnapshot> tilings;
  std::vector<TileInfo> tiles;
  for (int x = 0; x < 99; ++x) tiles.push_back(tile({x, 0, x + 1, 1}, 0.1f, 0.0f, 0.0f));
  tiles.push_back(tile({99, 0, 100, 1}, 10.0f, 0.0f, 0.0f));
  tilings[1] = snapshot(1, tiles);
  glm::vec3 full(-1.0f);
  const Image g = gradient_overlay(tilings, 100, 1, &full);
  EXPECT_FLOAT_EQ(full.x, 0.1f);
  EXPECT_FLOAT_EQ(g.at(5, 0).r, 1.0f);
  EXPECT_FLOAT_EQ(g.at(99, 0).r, 1.0f);  // clamped
  EXPECT_FLOAT_EQ(full.y, 0.0f);         // all flat: black
  EXPECT_FLOAT_EQ(g.at(5, 0).g, 0.0f);
}

TEST(OverlaysTest, DensityOverlayIsLogScaledToTheDensestPixel) {
  const std::vector<float> w = {0.0f, 1.0f, 3.0f, NAN};
  const Image d = density_overlay(w, 2, 2);
  EXPECT_EQ(d.at(0, 0), glm::vec3(0.0f));
  EXPECT_NEAR(d.at(1, 0).r, std::log1p(1.0f) / std::log1p(3.0f), 1e-6f);
  EXPECT_NEAR(d.at(0, 1).r, 1.0f, 1e-6f);
  EXPECT_EQ(d.at(1, 1), glm::vec3(0.0f));
}

}  // namespace
}  // namespace afr::service
