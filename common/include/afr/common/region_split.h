// Cutting an image region into parts for several workers (sampler threads, sampler nodes):
// the top of the K-D tree above every worker's own tiling (DESIGN.md, "The closed loop").
#pragma once

#include <afr/common/rect.h>

#include <span>
#include <vector>

namespace afr {

// Cuts `region` into shares.size() rectangles by recursive halving across the longer side,
// each part's area proportional to its share (shares > 0). The parts partition the region
// exactly and come back in the order of `shares`. A part is never empty as long as the region
// has at least shares.size() pixels; when it has fewer, the extra parts are empty.
std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares);

}  // namespace afr
