#include <afr/display/hole_fill.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr {
namespace {

// Level k texel (i, j) is the sum of the level-0 pixels of block [i 2^k, (i + 1) 2^k) x ...,
// summed directly (not level by level as the pyramid does).
glm::dvec4 block_sum(const std::vector<glm::vec4>& level0, int w, int h, int k, int i, int j) {
  glm::dvec4 s(0.0);
  const int side = 1 << k;
  for (int y = j * side; y < std::min(h, (j + 1) * side); ++y) {
    for (int x = i * side; x < std::min(w, (i + 1) * side); ++x) {
      s += glm::dvec4(level0[size_t(y) * size_t(w) + size_t(x)]);
    }
  }
  return s;
}

TEST(HoleFillTest, FillIsTheBilinearBlockAverageOfTheFirstLevelWithWeight) {
  const int w = 37, h = 23;
  Pcg32 rng(3);
  std::vector<glm::vec4> level0(size_t(w) * size_t(h), glm::vec4(0.0f));
  for (glm::vec4& p : level0) {
    if (rng.next_float() < 0.02f) {
      const float wt = 0.1f + rng.next_float();
      p = glm::vec4(rng.next_float() * wt, rng.next_float() * wt, rng.next_float() * wt, wt);
    }
  }
  HolePyramid pyramid;
  pyramid.build(level0, w, h);
  const std::vector<PyramidLevel> levels = pyramid_layout(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      glm::vec3 got;
      ASSERT_TRUE(pyramid.fill(x, y, &got));
      // Reference: first level whose bilinear interpolation has weight.
      bool found = false;
      glm::dvec3 want(0.0);
      for (int k = 1; k <= int(levels.size()) && !found; ++k) {
        const int lw = levels[size_t(k - 1)].width, lh = levels[size_t(k - 1)].height;
        const double px = (x + 0.5) / (1 << k) - 0.5, py = (y + 0.5) / (1 << k) - 0.5;
        const int ix = int(std::floor(px)), iy = int(std::floor(py));
        const double fx = px - ix, fy = py - iy;
        glm::dvec4 s(0.0);
        for (int b = 0; b < 2; ++b) {
          for (int a = 0; a < 2; ++a) {
            const double wt = (a ? fx : 1 - fx) * (b ? fy : 1 - fy);
            s += wt * block_sum(level0, w, h, k, std::clamp(ix + a, 0, lw - 1),
                                std::clamp(iy + b, 0, lh - 1));
          }
        }
        if (s.w > 0.0) {
          want = glm::dvec3(s) / s.w;
          found = true;
        }
      }
      ASSERT_TRUE(found);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 1e-5) << x << "," << y;
    }
  }
}

TEST(HoleFillTest, OneColorFillsWithThatColorAndNothingFillsBlack) {
  const int w = 20, h = 9;
  std::vector<glm::vec4> level0(size_t(w) * size_t(h), glm::vec4(0.0f));
  HolePyramid pyramid;
  pyramid.build(level0, w, h);
  glm::vec3 c(1.0f);
  EXPECT_FALSE(pyramid.fill(3, 4, &c));
  EXPECT_EQ(c, glm::vec3(0.0f));

  level0[5] = glm::vec4(0.25f, 0.5f, 1.0f, 1.0f) * 0.37f;
  level0[150] = glm::vec4(0.25f, 0.5f, 1.0f, 1.0f) * 2.0f;
  pyramid.build(level0, w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      ASSERT_TRUE(pyramid.fill(x, y, &c));
      EXPECT_NEAR(c.r, 0.25f, 1e-6f);
      EXPECT_NEAR(c.g, 0.5f, 1e-6f);
      EXPECT_NEAR(c.b, 1.0f, 1e-6f);
    }
  }
}

TEST(HoleFillTest, LayoutHalvesUpToOnePixel) {
  const std::vector<PyramidLevel> levels = pyramid_layout(5, 3);
  ASSERT_EQ(levels.size(), 3u);
  EXPECT_EQ(levels[0].width, 3);
  EXPECT_EQ(levels[0].height, 2);
  EXPECT_EQ(levels[1].width, 2);
  EXPECT_EQ(levels[1].height, 1);
  EXPECT_EQ(levels[2].width, 1);
  EXPECT_EQ(levels[2].row_offset, 3);
  EXPECT_EQ(pyramid_atlas_height(levels), 4);
  EXPECT_TRUE(pyramid_layout(1, 1).empty());
}

}  // namespace
}  // namespace afr
