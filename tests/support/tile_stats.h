// The statistics of a sampler tile recomputed by brute force from its deep buffer, straight
// from the definitions of section 4 (in long double): the reference the incremental
// statistics are tested against (tests/sampler_node, tests/extremes).
#pragma once

#include <afr/sampler/sampler.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace afr::testing {

// The statistics of a tile straight from the crosshairs in its block: weights exp(-3.47 age)
// taken relative to the newest crosshair (the same ratios, finite for any age), variance as
// E[L^2] - E[L]^2 in long double; the occluded count with each crosshair's absolute weight.
inline TileStats brute_force_stats(const Sampler& s, int tile, double now) {
  const PixelRect rect = s.tiling().node(tile).rect;
  const DeepBuffer& b = s.buffer();
  TileStats st;
  double newest = -std::numeric_limits<double>::infinity();
  for (int32_t y = rect.y0; y < rect.y1; ++y) {
    for (int32_t x = rect.x0; x < rect.x1; ++x) {
      for (int k = 0; k < b.count(x, y); ++k) newest = std::max(newest, b.at(x, y, k).time);
    }
  }
  long double w = 0, wl = 0, wll = 0, wgx = 0, wgy = 0, wt = 0, wgt = 0, age = 0, occluded = 0;
  for (int32_t y = rect.y0; y < rect.y1; ++y) {
    for (int32_t x = rect.x0; x < rect.x1; ++x) {
      for (int k = 0; k < b.count(x, y); ++k) {
        const Crosshair& c = b.at(x, y, k);
        const long double wi = std::exp(-(long double)kAgeDecay * (newest - c.time));
        w += wi;
        wl += wi * c.luminance;
        wll += wi * c.luminance * c.luminance;
        wgx += wi * c.G_x;
        wgy += wi * c.G_y;
        if (c.has(Crosshair::kHasTemporalGradient)) {
          wt += wi;
          wgt += wi * c.G_t;
        }
        age += now - c.time;
        ++st.count;
        if (c.has(Crosshair::kOccluded)) {
          occluded += std::exp(-(long double)kAgeDecay * (now - c.time));
        }
      }
    }
  }
  if (st.count == 0) return st;
  const long double mean = wl / w;
  st.v = double(wll / w - mean * mean);
  st.G_x = double(wgx / w);
  st.G_y = double(wgy / w);
  st.G_t = wt > 0 ? double(wgt / wt) : 0.0;
  st.mean_age = double(age / st.count);
  st.occluded = double(occluded);
  return st;
}

}  // namespace afr::testing
