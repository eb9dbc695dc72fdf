// Holes: a pixel that no splat reaches (weight exactly 0) takes the color of wider support.
// The accumulated (sum w c, sum w) of the image is summed 2 x 2 into a pyramid, level by
// level to 1 x 1; a hole takes the normalised bilinear interpolation of the first level that
// has weight at its position. The result is a smooth fill from the nearest samples; only an
// image with no weight at all is black. The OpenGL backend runs the same arithmetic in
// compute shaders on the same layout.
#pragma once

#include <afr/common/math.h>

#include <vector>

namespace afr {

// Level k >= 1 is ceil(w / 2^k) x ceil(h / 2^k); the levels are stacked top to bottom in one
// atlas ceil(w / 2) wide, level k starting at row `row_offset`.
struct PyramidLevel {
  int width = 0;
  int height = 0;
  int row_offset = 0;
};
std::vector<PyramidLevel> pyramid_layout(int width, int height);
int pyramid_atlas_height(const std::vector<PyramidLevel>& levels);

class HolePyramid {
 public:
  // level0: width x height (sum of w * color, sum of w), row 0 at the top.
  void build(const std::vector<glm::vec4>& level0, int width, int height);
  // The fill color of pixel (x, y). False (color black) when the image has no weight at all.
  bool fill(int x, int y, glm::vec3* color) const;

 private:
  glm::vec4 texel(int level, int x, int y) const;

  std::vector<PyramidLevel> levels_;  // levels_[k - 1] is level k
  int atlas_width_ = 0;
  std::vector<glm::vec4> atlas_;
};

}  // namespace afr
