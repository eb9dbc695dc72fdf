#include <afr/display/tile_field.h>

#include <gtest/gtest.h>
#include <glm/glm.hpp>

#include <algorithm>
#include <limits>

namespace afr {
namespace {

TileInfo tile(int x0, int y0, int x1, int y1, float g, float rate = 5.0f) {
  TileInfo t;
  t.rect = PixelRect{x0, y0, x1, y1};
  t.G_x = g;
  t.G_y = 2 * g;
  t.G_t = 3 * g;
  t.rate = rate;
  return t;
}

TilingSnapshot snapshot(uint32_t id, double time, PixelRect region, std::vector<TileInfo> tiles) {
  TilingSnapshot s;
  s.sampler_id = id;
  s.time = time;
  s.region = region;
  s.tiles = std::move(tiles);
  return s;
}

TEST(TileFieldTest, EveryPixelReadsTheTileThatCoversIt) {
  TileField field(8, 6);
  field.set_tiling(
      snapshot(0, 1.0, {0, 0, 8, 6},
               {tile(0, 0, 4, 3, 0.1f), tile(4, 0, 8, 3, 0.2f), tile(0, 3, 8, 5, 0.3f)}));
  EXPECT_TRUE(field.update(8, 6));
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) {
      const float want = y < 3 ? (x < 4 ? 0.1f : 0.2f) : (y < 5 ? 0.3f : 0.0f);
      EXPECT_FLOAT_EQ(field.at(x, y).G_x, want) << x << "," << y;
      EXPECT_FLOAT_EQ(field.at(x, y).G_y, 2 * want);
      EXPECT_FLOAT_EQ(field.at(x, y).G_t, 3 * want);
    }
  }
  EXPECT_EQ(field.at(0, 5).rate, 0.0f);  // uncovered: unknown rate
  EXPECT_FALSE(field.update(8, 6));      // nothing new
}

TEST(TileFieldTest, TilesLargerThanTheRateLatticeEnterAsTheirPiecesInItsCells) {
  // kRateLattice = 32: a tile wider or taller is cut along the lattice's lines on the axes
  // where it is; one within it on both axes stays whole, wherever it lies.
  ASSERT_EQ(kRateLattice, 32);
  TileField field(128, 96);
  field.set_tiling(snapshot(0, 1.0, {0, 0, 128, 96},
                            {tile(10, 0, 90, 20, 0.1f),       // 80 wide: x pieces
                             tile(100, 10, 120, 80, 0.2f),    // 70 tall: y pieces
                             tile(20, 40, 52, 72, 0.3f),      // 32 x 32 across lattice lines: whole
                             tile(60, 30, 100, 70, 0.4f)}));  // 40 x 40: both axes
  EXPECT_TRUE(field.update(128, 96));
  std::vector<PixelRect> got;
  for (size_t i = 1; i < field.tiles().size(); ++i) got.push_back(field.tiles()[i].rect);
  const std::vector<PixelRect> want = {
      {10, 0, 32, 20},    {32, 0, 64, 20},    {64, 0, 90, 20},  {100, 10, 120, 32},
      {100, 32, 120, 64}, {100, 64, 120, 80}, {20, 40, 52, 72}, {60, 30, 64, 32},
      {64, 30, 96, 32},   {96, 30, 100, 32},  {60, 32, 64, 64}, {64, 32, 96, 64},
      {96, 32, 100, 64},  {60, 64, 64, 70},   {64, 64, 96, 70}, {96, 64, 100, 70}};
  EXPECT_EQ(got, want);
  // The pieces keep their tile's values, and every pixel still reads its tile's.
  for (size_t i = 1; i < field.tiles().size(); ++i) {
    const FieldTile& t = field.tiles()[i];
    EXPECT_FLOAT_EQ(t.G_y, 2 * t.G_x);
    EXPECT_EQ(t.rate, 5.0f);
  }
  EXPECT_FLOAT_EQ(field.at(89, 19).G_x, 0.1f);
  EXPECT_FLOAT_EQ(field.at(100, 79).G_x, 0.2f);
  EXPECT_FLOAT_EQ(field.at(60, 69).G_x, 0.4f);
  EXPECT_FLOAT_EQ(field.at(51, 71).G_x, 0.3f);
  // A grid over part of the image keeps only the pieces that reach it.
  EXPECT_TRUE(field.update(PixelGrid{16, 16, 66, 40, 1.0, 1.0}));
  got.clear();
  for (size_t i = 1; i < field.tiles().size(); ++i) got.push_back(field.tiles()[i].rect);
  EXPECT_EQ(got, (std::vector<PixelRect>{{64, 32, 96, 64}}));
}

TEST(TileFieldTest, AnImageDrawnSmallerCutsOnACoarserLattice) {
  // At least kRateLattice output pixels a cell, in powers of two.
  EXPECT_EQ(rate_lattice(1.0, 1.0), 32);
  EXPECT_EQ(rate_lattice(4.0, 2.0), 32);
  EXPECT_EQ(rate_lattice(0.5, 0.5), 64);
  EXPECT_EQ(rate_lattice(0.4, 1.0), 128);  // the smaller axis decides
  EXPECT_EQ(rate_lattice(1.0 / 64.0, 1.0 / 64.0), 2048);
  EXPECT_EQ(rate_lattice(1e-9, 1e-9), 32768);
  // A 256 x 256 tile drawn at half size: 4 x 4 pieces of 64, not 8 x 8 of 32.
  TileField field(256, 256);
  field.set_tiling(snapshot(0, 1.0, {0, 0, 256, 256}, {tile(0, 0, 256, 256, 0.1f)}));
  EXPECT_TRUE(field.update(PixelGrid{128, 128, 0, 0, 0.5, 0.5}));
  ASSERT_EQ(field.tiles().size(), 1u + 16u);
  for (size_t i = 1; i < field.tiles().size(); ++i) {
    EXPECT_EQ(field.tiles()[i].rect.width(), 64);
    EXPECT_EQ(field.tiles()[i].rect.height(), 64);
  }
  // The 32768 x 32768 image drawn at 512 x 512: 16 x 16 pieces of 2048.
  TileField huge(32768, 32768);
  huge.set_tiling(snapshot(0, 1.0, {0, 0, 32768, 32768}, {tile(0, 0, 32768, 32768, 0.1f)}));
  EXPECT_TRUE(huge.update(512, 512));
  EXPECT_EQ(huge.tiles().size(), 1u + 256u);
}

TEST(TileFieldTest, NewerSnapshotsReplaceOlderOnesOfTheSameSampler) {
  TileField field(4, 4);
  field.set_tiling(snapshot(0, 2.0, {0, 0, 4, 4}, {tile(0, 0, 4, 4, 0.5f)}));
  field.set_tiling(snapshot(0, 1.0, {0, 0, 4, 4}, {tile(0, 0, 4, 4, 0.9f)}));  // stale
  field.update(4, 4);
  EXPECT_FLOAT_EQ(field.at(1, 1).G_x, 0.5f);
  EXPECT_EQ(field.stats().stale_snapshots, 1u);
  field.set_tiling(snapshot(0, 3.0, {0, 0, 4, 4}, {tile(0, 0, 2, 4, 0.7f)}));
  EXPECT_TRUE(field.update(4, 4));
  EXPECT_FLOAT_EQ(field.at(1, 1).G_x, 0.7f);
  EXPECT_FLOAT_EQ(field.at(3, 1).G_x, 0.0f);  // the old snapshot is gone entirely
}

TEST(TileFieldTest, SamplersShareTheImageAndTheNewestWinsWhereRegionsOverlap) {
  TileField field(8, 4);
  field.set_tiling(snapshot(1, 5.0, {0, 0, 5, 4}, {tile(0, 0, 5, 4, 0.1f)}));
  field.set_tiling(snapshot(2, 4.0, {3, 0, 8, 4}, {tile(3, 0, 8, 4, 0.2f)}));
  field.update(8, 4);
  EXPECT_FLOAT_EQ(field.at(0, 0).G_x, 0.1f);
  EXPECT_FLOAT_EQ(field.at(4, 0).G_x, 0.1f);  // both cover it; sampler 1's is newer
  EXPECT_FLOAT_EQ(field.at(7, 3).G_x, 0.2f);
  EXPECT_EQ(field.at(7, 3).sampler_id, 2u);
}

TEST(TileFieldTest, AForgottenSamplersTilesNoLongerShapeTheField) {
  TileField field(8, 4);
  field.set_tiling(snapshot(1, 5.0, {0, 0, 5, 4}, {tile(0, 0, 5, 4, 0.1f)}));
  field.set_tiling(snapshot(2, 4.0, {3, 0, 8, 4}, {tile(3, 0, 8, 4, 0.2f)}));
  field.update(8, 4);
  EXPECT_EQ(field.at(4, 0).sampler_id, 1u);
  field.forget(1);
  EXPECT_TRUE(field.update(8, 4));
  EXPECT_EQ(field.tiles().size(), 2u);  // the "no tile" entry and sampler 2's
  EXPECT_EQ(field.at(4, 0).sampler_id, 2u);
  EXPECT_FLOAT_EQ(field.at(0, 0).G_x, 0.0f);  // no tile there any more
  field.forget(7);                            // none held: nothing changes
  EXPECT_FALSE(field.update(8, 4));
}

TEST(TileFieldTest, TilesAreClippedToTheirRegionAndBadValuesZeroed) {
  TileField field(6, 6);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  TileInfo bad = tile(0, 3, 3, 6, 0.1f);
  bad.G_x = nan;
  bad.G_t = -1.0f;
  bad.rate = std::numeric_limits<float>::infinity();
  field.set_tiling(
      snapshot(0, 1.0, {0, 0, 3, 6}, {tile(-5, -5, 100, 3, 0.4f), bad, tile(4, 4, 6, 6, 0.8f)}));
  field.update(6, 6);
  EXPECT_FLOAT_EQ(field.at(2, 2).G_x, 0.4f);
  EXPECT_FLOAT_EQ(field.at(3, 2).G_x, 0.0f);  // outside the region
  EXPECT_FLOAT_EQ(field.at(1, 4).G_x, 0.0f);
  EXPECT_FLOAT_EQ(field.at(1, 4).G_y, 0.2f);
  EXPECT_FLOAT_EQ(field.at(1, 4).G_t, 0.0f);
  EXPECT_FLOAT_EQ(field.at(1, 4).rate, 0.0f);
  EXPECT_FLOAT_EQ(field.at(5, 5).G_x, 0.0f);
  const TileFieldStats st = field.stats();
  EXPECT_EQ(st.bad_values, 3u);
  EXPECT_EQ(st.dropped_tiles, 1u);
}

TEST(TileFieldTest, ScaledOutputsMapPixelCentersIntoTiles) {
  TileField field(4, 4);
  field.set_tiling(
      snapshot(0, 1.0, {0, 0, 4, 4}, {tile(0, 0, 1, 4, 0.1f), tile(1, 0, 4, 4, 0.2f)}));
  EXPECT_TRUE(field.update(8, 2));  // a new size rebuilds the map
  // Output pixel i has its center at (i + 0.5) / 2 in the sampling image.
  EXPECT_FLOAT_EQ(field.at(0, 0).G_x, 0.1f);
  EXPECT_FLOAT_EQ(field.at(1, 1).G_x, 0.1f);
  EXPECT_FLOAT_EQ(field.at(2, 0).G_x, 0.2f);
  EXPECT_FLOAT_EQ(field.at(7, 1).G_x, 0.2f);
}

// A GPU backend builds the map from spans(): each pixel takes the highest tile index whose span
// holds it. That rule must give the CPU's map exactly, overlaps and lattice pieces included.
TEST(TileFieldTest, SpansGiveTheIndexMapByTheHighestIndexThatCoversAPixel) {
  for (const glm::ivec2 size : {glm::ivec2(100, 70), glm::ivec2(37, 150)}) {
    TileField with_map(100, 80), without(100, 80);
    without.set_index_map(false);
    std::vector<TileInfo> left, right;
    for (int y = 0; y < 80; y += 10) {
      for (int x = 0; x < 60; x += 15) left.push_back(tile(x, y, x + 15, y + 10, 0.1f));
    }
    right.push_back(tile(40, 0, 100, 80, 0.2f));  // larger than the lattice: cut into pieces
    right.push_back(tile(45, 30, 70, 50, 0.3f));
    for (TileField* f : {&with_map, &without}) {
      f->set_tiling(snapshot(1, 2.0, {0, 0, 60, 80}, left));
      f->set_tiling(snapshot(2, 1.0, {40, 0, 100, 80}, right));  // older: loses the overlap
    }
    EXPECT_TRUE(with_map.update(size.x, size.y));
    EXPECT_TRUE(without.update(size.x, size.y));
    EXPECT_TRUE(without.index_map().empty());
    ASSERT_EQ(with_map.spans(), without.spans());
    ASSERT_EQ(with_map.spans().size(), with_map.tiles().size());
    std::vector<uint32_t> map(size_t(size.x) * size_t(size.y), 0u);
    for (uint32_t i = 1; i < with_map.spans().size(); ++i) {
      const PixelRect& s = with_map.spans()[i];
      for (int y = s.y0; y < s.y1; ++y) {
        for (int x = s.x0; x < s.x1; ++x) {
          uint32_t& m = map[size_t(y) * size_t(size.x) + size_t(x)];
          m = std::max(m, i);
        }
      }
    }
    EXPECT_EQ(map, with_map.index_map());
    // Sampling pixel (50, 35) lies in both samplers' tiles: the newer snapshot's (sampler 1).
    const int gx = int(50.5 * size.x / 100.0), gy = int(35.5 * size.y / 80.0);
    EXPECT_EQ(with_map.at(gx, gy).sampler_id, 1u);
    const int hx = int(80.5 * size.x / 100.0);
    EXPECT_EQ(with_map.at(hx, gy).sampler_id, 2u);
  }
}

}  // namespace
}  // namespace afr
