#include <afr/sampler/tiling.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

namespace afr {
namespace {

// Independent of KdTiling::is_valid: every pixel lies in exactly one listed tile.
void expect_exact_partition(const KdTiling& t) {
  const PixelRect r = t.region();
  std::vector<int> cover(size_t(r.area()), 0);
  for (int id : t.tiles()) {
    const PixelRect q = t.node(id).rect;
    for (int32_t y = q.y0; y < q.y1; ++y) {
      for (int32_t x = q.x0; x < q.x1; ++x) ++cover[size_t(y - r.y0) * r.width() + (x - r.x0)];
    }
  }
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = r.x0; x < r.x1; ++x) {
      ASSERT_EQ(cover[size_t(y - r.y0) * r.width() + (x - r.x0)], 1) << x << "," << y;
      const int id = t.tile_at(x, y);
      ASSERT_TRUE(t.node(id).rect.contains(x, y));
    }
  }
}

TEST(TilingTest, StartsAsOneTileCoveringTheRegion) {
  KdTiling t(PixelRect{3, 5, 40, 29});
  EXPECT_EQ(t.tile_count(), 1);
  EXPECT_EQ(t.node(t.tiles()[0]).rect, (PixelRect{3, 5, 40, 29}));
  EXPECT_TRUE(t.is_valid());
}

TEST(TilingTest, SplitHalvesTheLongerSide) {
  KdTiling t(PixelRect{0, 0, 10, 4});
  int a, b;
  t.split(t.root(), &a, &b);
  EXPECT_EQ(t.node(a).rect, (PixelRect{0, 0, 5, 4}));
  EXPECT_EQ(t.node(b).rect, (PixelRect{5, 0, 10, 4}));
  int c, d;
  t.split(a, &c, &d);  // 5 x 4: still wider than tall
  EXPECT_EQ(t.node(c).rect, (PixelRect{0, 0, 2, 4}));
  EXPECT_EQ(t.node(d).rect, (PixelRect{2, 0, 5, 4}));
}

TEST(TilingTest, OnePixelTilesCannotSplit) {
  KdTiling t(PixelRect{0, 0, 2, 1});
  int a, b;
  t.split(t.root(), &a, &b);
  EXPECT_FALSE(t.can_split(a));
  EXPECT_FALSE(t.can_split(b));
  KdTiling single(PixelRect{7, 7, 8, 8});
  EXPECT_FALSE(single.can_split(single.root()));
}

TEST(TilingTest, DepthIsBounded) {
  KdTiling t(PixelRect{0, 0, 1024, 1024}, 3);
  int leaf = t.root();
  for (int depth = 0; depth < 3; ++depth) {
    int a, b;
    t.split(leaf, &a, &b);
    leaf = a;
  }
  EXPECT_FALSE(t.can_split(leaf));
}

TEST(TilingTest, MergeKeepsTilesAPartitionOverRandomSequences) {
  Pcg32 rng(42);
  for (int run = 0; run < 20; ++run) {
    const int32_t w = 1 + int32_t(rng.next_below(48)), h = 1 + int32_t(rng.next_below(48));
    const int32_t x0 = int32_t(rng.next_below(100)), y0 = int32_t(rng.next_below(100));
    KdTiling tiling(PixelRect{x0, y0, x0 + w, y0 + h});
    for (int op = 0; op < 300; ++op) {
      if (rng.next_below(2) == 0) {
        const int leaf = tiling.tiles()[rng.next_below(uint32_t(tiling.tile_count()))];
        if (tiling.can_split(leaf)) tiling.split(leaf, nullptr, nullptr);
      } else if (!tiling.mergeable().empty()) {
        const int p = tiling.mergeable()[rng.next_below(uint32_t(tiling.mergeable().size()))];
        ASSERT_TRUE(tiling.can_merge(p));
        tiling.merge(p);
      }
      ASSERT_TRUE(tiling.is_valid());
      if (op % 50 == 0) expect_exact_partition(tiling);
    }
    expect_exact_partition(tiling);
  }
}

// Every pixel lies in exactly one cell, the cell cell_at names; every node no deeper than the
// cells is exactly the union of its cell range.
void expect_cells_match_nodes(const KdTiling& t, int cell_pixels) {
  const PixelRect r = t.region();
  std::vector<int> cover(size_t(r.area()), 0);
  for (int c = 0; c < t.cell_count(); ++c) {
    const PixelRect q = t.cell_rect(c);
    EXPECT_GE(2 * q.area(), cell_pixels);
    for (int32_t y = q.y0; y < q.y1; ++y) {
      for (int32_t x = q.x0; x < q.x1; ++x) {
        ++cover[size_t(y - r.y0) * r.width() + (x - r.x0)];
        ASSERT_EQ(t.cell_at(x, y), c);
      }
    }
  }
  for (int n : cover) ASSERT_EQ(n, 1);
  std::vector<int> stack = {t.root()};
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    if (!t.covers_cells(id)) continue;
    int64_t area = 0;
    for (int c = t.first_cell(id); c < t.first_cell(id) + t.cells_in(id); ++c) {
      const PixelRect q = t.cell_rect(c);
      const PixelRect n = t.node(id).rect;
      ASSERT_TRUE(q.x0 >= n.x0 && q.x1 <= n.x1 && q.y0 >= n.y0 && q.y1 <= n.y1) << id;
      area += q.area();
    }
    ASSERT_EQ(area, t.node(id).rect.area());
    if (!t.node(id).is_leaf()) {
      stack.push_back(t.node(id).child[0]);
      stack.push_back(t.node(id).child[1]);
    }
  }
}

TEST(TilingTest, CellsAreTheNodesOfOneDepthOverRandomSequences) {
  Pcg32 rng(7);
  for (int run = 0; run < 20; ++run) {
    const int32_t w = 1 + int32_t(rng.next_below(80)), h = 1 + int32_t(rng.next_below(80));
    const int32_t x0 = int32_t(rng.next_below(100)), y0 = int32_t(rng.next_below(100));
    const int cell_pixels = 1 + int(rng.next_below(40));
    KdTiling tiling(PixelRect{x0, y0, x0 + w, y0 + h}, 40, cell_pixels);
    // As deep as it can be: one level more would make a cell smaller than cell_pixels / 2.
    EXPECT_EQ(tiling.cell_count(), 1 << tiling.cell_depth());
    expect_cells_match_nodes(tiling, std::min<int>(cell_pixels, w * h * 2));
    for (int op = 0; op < 300; ++op) {
      if (rng.next_below(2) == 0) {
        const int leaf = tiling.tiles()[rng.next_below(uint32_t(tiling.tile_count()))];
        if (tiling.can_split(leaf)) tiling.split(leaf, nullptr, nullptr);
      } else if (!tiling.mergeable().empty()) {
        tiling.merge(tiling.mergeable()[rng.next_below(uint32_t(tiling.mergeable().size()))]);
      }
      ASSERT_TRUE(tiling.is_valid());
      // tile_at starts from the cells: it must still find the tile of every pixel.
      if (op % 25 == 0) expect_exact_partition(tiling);
      if (op % 100 == 0) expect_cells_match_nodes(tiling, std::min<int>(cell_pixels, w * h * 2));
    }
    expect_exact_partition(tiling);
  }
}

TEST(TilingTest, TheCellOfAPixelIsTheSameFromTheRootAndFromItsTile) {
  // cell_of starts from a tile (or takes its ancestor at cell depth), tile_at hands out the cell
  // it started from: both must name the cell that holds the pixel, as cell_rect says.
  Pcg32 rng(11);
  for (int run = 0; run < 20; ++run) {
    const int32_t w = 1 + int32_t(rng.next_below(70)), h = 1 + int32_t(rng.next_below(70));
    const int32_t x0 = int32_t(rng.next_below(50)), y0 = int32_t(rng.next_below(50));
    KdTiling tiling(PixelRect{x0, y0, x0 + w, y0 + h}, 40, 1 + int(rng.next_below(40)));
    for (int op = 0; op < 200; ++op) {
      if (rng.next_below(3) != 0) {
        const int leaf = tiling.tiles()[rng.next_below(uint32_t(tiling.tile_count()))];
        if (tiling.can_split(leaf)) tiling.split(leaf, nullptr, nullptr);
      } else if (!tiling.mergeable().empty()) {
        tiling.merge(tiling.mergeable()[rng.next_below(uint32_t(tiling.mergeable().size()))]);
      }
      if (op % 20 != 0) continue;
      for (int32_t y = y0; y < y0 + h; ++y) {
        for (int32_t x = x0; x < x0 + w; ++x) {
          int cell = -1;
          const int tile = tiling.tile_at(x, y, &cell);
          ASSERT_TRUE(tiling.cell_rect(cell).contains(x, y)) << x << "," << y;
          ASSERT_EQ(tiling.cell_at(x, y), cell);
          ASSERT_EQ(tiling.cell_of(tile, x, y), cell);
          ASSERT_EQ(tiling.cell_of(tiling.root(), x, y), cell);
        }
      }
    }
  }
}

TEST(TilingTest, MergeableListsExactlyTheParentsOfTwoLeaves) {
  KdTiling t(PixelRect{0, 0, 16, 16});
  int a, b, c, d;
  t.split(t.root(), &a, &b);
  EXPECT_EQ(t.mergeable(), std::vector<int>{t.root()});
  t.split(a, &c, &d);
  // The root now has a non-leaf child; only a can merge.
  EXPECT_EQ(t.mergeable(), std::vector<int>{a});
  t.merge(a);
  EXPECT_EQ(t.mergeable(), std::vector<int>{t.root()});
  t.merge(t.root());
  EXPECT_TRUE(t.mergeable().empty());
  EXPECT_EQ(t.tile_count(), 1);
}

TEST(TilingTest, HugeRegionNeedsNoPerPixelMemory) {
  // 32768 x 32768: tile_at must work without anything proportional to the area.
  KdTiling t(PixelRect{0, 0, 32768, 32768});
  int leaf = t.root();
  for (int k = 0; k < 30; ++k) {
    int a, b;
    t.split(leaf, &a, &b);
    leaf = b;
  }
  EXPECT_EQ(t.tile_at(32767, 32767), leaf);
  EXPECT_EQ(t.node(leaf).rect.area(), 1);
  EXPECT_TRUE(t.is_valid());
}

}  // namespace
}  // namespace afr
