#include <afr/display/hole_fill.h>

#include <algorithm>
#include <cmath>

namespace afr {

std::vector<PyramidLevel> pyramid_layout(int width, int height) {
  std::vector<PyramidLevel> levels;
  int w = width, h = height, row = 0;
  while (w > 1 || h > 1) {
    w = (w + 1) / 2;
    h = (h + 1) / 2;
    levels.push_back(PyramidLevel{w, h, row});
    row += h;
  }
  return levels;
}

int pyramid_atlas_height(const std::vector<PyramidLevel>& levels) {
  return levels.empty() ? 1 : levels.back().row_offset + levels.back().height;
}

void HolePyramid::build(const std::vector<glm::vec4>& level0, int width, int height) {
  levels_ = pyramid_layout(width, height);
  atlas_width_ = std::max(1, (width + 1) / 2);
  atlas_.assign(size_t(atlas_width_) * size_t(pyramid_atlas_height(levels_)), glm::vec4(0.0f));
  int src_w = width, src_h = height;
  const glm::vec4* src = level0.data();
  size_t src_stride = size_t(width);
  for (const PyramidLevel& L : levels_) {
    glm::vec4* dst = atlas_.data() + size_t(L.row_offset) * size_t(atlas_width_);
    for (int y = 0; y < L.height; ++y) {
      for (int x = 0; x < L.width; ++x) {
        // The same order as the GL compute shader: (0,0), (1,0), (0,1), (1,1).
        glm::vec4 s(0.0f);
        for (int b = 0; b < 2; ++b) {
          for (int a = 0; a < 2; ++a) {
            const int sx = 2 * x + a, sy = 2 * y + b;
            if (sx < src_w && sy < src_h) s += src[size_t(sy) * src_stride + size_t(sx)];
          }
        }
        dst[size_t(y) * size_t(atlas_width_) + size_t(x)] = s;
      }
    }
    src = dst;
    src_stride = size_t(atlas_width_);
    src_w = L.width;
    src_h = L.height;
  }
}

glm::vec4 HolePyramid::texel(int level, int x, int y) const {
  const PyramidLevel& L = levels_[size_t(level - 1)];
  x = std::clamp(x, 0, L.width - 1);
  y = std::clamp(y, 0, L.height - 1);
  return atlas_[size_t(L.row_offset + y) * size_t(atlas_width_) + size_t(x)];
}

bool HolePyramid::fill(int x, int y, glm::vec3* color) const {
  for (int k = 1; k <= int(levels_.size()); ++k) {
    // Level-0 pixel center (x + 0.5) in level-k texels, whose centers are at i + 0.5.
    const float inv = 1.0f / float(1 << k);
    const float px = (float(x) + 0.5f) * inv - 0.5f;
    const float py = (float(y) + 0.5f) * inv - 0.5f;
    const float fx0 = std::floor(px), fy0 = std::floor(py);
    const float fx = px - fx0, fy = py - fy0;
    const int ix = int(fx0), iy = int(fy0);
    const glm::vec4 s =
        texel(k, ix, iy) * ((1.0f - fx) * (1.0f - fy)) + texel(k, ix + 1, iy) * (fx * (1.0f - fy)) +
        texel(k, ix, iy + 1) * ((1.0f - fx) * fy) + texel(k, ix + 1, iy + 1) * (fx * fy);
    if (s.w > 0.0f) {
      *color = glm::vec3(s) / s.w;
      return true;
    }
  }
  *color = glm::vec3(0.0f);
  return false;
}

}  // namespace afr
