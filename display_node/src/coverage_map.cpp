#include <afr/display/coverage_map.h>

namespace afr {

void CoverageMap::reset(int width, int height) {
  width_ = width;
  height_ = height;
  valid_ = false;
  cells_.assign(size_t(width) * size_t(height), CoverageCell{});
}

}  // namespace afr
