#include <afr/common/region_split.h>

#include <afr/common/check.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace afr {

namespace {

void split(const PixelRect& r, std::span<const double> shares, size_t first,
           std::vector<PixelRect>* out) {
  if (shares.size() == 1) {
    (*out)[first] = r;
    return;
  }
  const size_t half = shares.size() / 2;
  const double left = std::accumulate(shares.begin(), shares.begin() + half, 0.0);
  const double total = std::accumulate(shares.begin(), shares.end(), 0.0);
  const bool across_x = r.width() >= r.height();
  const int32_t extent = across_x ? r.width() : r.height();
  // Each side keeps at least as many pixel columns (rows) as it has parts, when it can.
  const int32_t lo = std::min<int32_t>(int32_t(half), extent);
  const int32_t hi = std::max<int32_t>(lo, extent - int32_t(shares.size() - half));
  const int32_t cut = std::clamp(int32_t(std::lround(extent * left / total)), lo, hi);
  PixelRect a = r, b = r;
  if (across_x) {
    a.x1 = b.x0 = r.x0 + cut;
  } else {
    a.y1 = b.y0 = r.y0 + cut;
  }
  split(a, shares.subspan(0, half), first, out);
  split(b, shares.subspan(half), first + half, out);
}

}  // namespace

std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares) {
  AFR_CHECK(!shares.empty());
  for (double s : shares) AFR_CHECK(s > 0.0 && std::isfinite(s));
  std::vector<PixelRect> out(shares.size());
  split(region, shares, 0, &out);
  return out;
}

}  // namespace afr
