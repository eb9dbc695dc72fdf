#include <afr/display/coverage_map.h>

#include <algorithm>

namespace afr {

float splat_radius(const CoverageCell* previous, float filter_radius, const SplatSizeRule& rule) {
  // Section 6.2: splat size from the previous image's coverage.
  float r = filter_radius;
  if (previous != nullptr) {
    if (!(previous->count > 0.0f)) {
      r = rule.grow * filter_radius;
    } else {
      const float mean = previous->radius_sum / previous->count;
      if (previous->count < rule.grow_below) {
        r = rule.grow * mean;
      } else if (previous->count > rule.shrink_above) {
        r = rule.shrink * mean;
      } else {
        r = mean;
      }
    }
  }
  if (!(r >= rule.min_radius)) return rule.min_radius;  // NaN too
  return std::min(r, rule.max_radius);
}

void CoverageMap::reset(int width, int height) {
  width_ = width;
  height_ = height;
  valid_ = false;
  cells_.assign(size_t(width) * size_t(height), CoverageCell{});
}

}  // namespace afr
