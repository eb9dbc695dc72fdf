// Shared pieces of the numerical-extremes tests: checks that every value a part hands on is
// finite, and an independent, brute-force recomputation of a sampler tile's statistics from
// its deep buffer (the definitions of section 4, in long double).
#pragma once

#include <afr/common/samples.h>
#include <afr/sampler/sampler.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace afr::extremes {

inline bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Every field of a sample is finite and its image position inside the width x height image,
// as the protocol requires of what a sampler sends.
inline ::testing::AssertionResult sample_is_sane(const Sample& s, int width, int height) {
  if (!std::isfinite(s.time)) return ::testing::AssertionFailure() << "time " << s.time;
  if (!(s.x >= 0.0f && s.x < float(width)) || !(s.y >= 0.0f && s.y < float(height))) {
    return ::testing::AssertionFailure()
           << "position (" << s.x << ", " << s.y << ") outside " << width << "x" << height;
  }
  if (!finite3(s.color) || s.color.r < 0.0f || s.color.g < 0.0f || s.color.b < 0.0f) {
    return ::testing::AssertionFailure()
           << "color " << s.color.r << " " << s.color.g << " " << s.color.b;
  }
  if (!finite3(s.position) || !finite3(s.velocity)) {
    return ::testing::AssertionFailure() << "world position or velocity not finite";
  }
  return ::testing::AssertionSuccess();
}

inline ::testing::AssertionResult snapshot_is_sane(const TilingSnapshot& snap) {
  if (!std::isfinite(snap.time)) return ::testing::AssertionFailure() << "snapshot time";
  for (const TileInfo& t : snap.tiles) {
    const float values[] = {t.G_x, t.G_y, t.G_t, t.v, t.E, t.rate};
    for (float v : values) {
      if (!std::isfinite(v) || v < 0.0f) {
        return ::testing::AssertionFailure()
               << "tile [" << t.rect.x0 << "," << t.rect.x1 << ")x[" << t.rect.y0 << ","
               << t.rect.y1 << "): G_x " << t.G_x << " G_y " << t.G_y << " G_t " << t.G_t << " v "
               << t.v << " E " << t.E << " rate " << t.rate;
      }
    }
  }
  return ::testing::AssertionSuccess();
}

// The statistics of a tile straight from the crosshairs in its block: weights exp(-3.47 age)
// taken relative to the newest crosshair (the same ratios, finite for any age), variance as
// E[L^2] - E[L]^2 in long double.
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
  long double w = 0, wl = 0, wll = 0, wgx = 0, wgy = 0, wt = 0, wgt = 0, age = 0;
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
  return st;
}

// Every tile's incremental statistics equal the brute-force ones (relative tolerance `rel`,
// with an absolute floor of 1e-9 luminance units, far below any step of a display, for values
// near zero), and the variance is never negative.
inline ::testing::AssertionResult stats_match_buffer(const Sampler& s, double now,
                                                     double rel = 1e-6) {
  for (int t : s.tiling().tiles()) {
    const TileStats inc = s.tile_stats(t);
    const TileStats ref = brute_force_stats(s, t, now);
    if (inc.count != ref.count) {
      return ::testing::AssertionFailure()
             << "tile " << t << " count " << inc.count << " vs " << ref.count;
    }
    if (!(inc.v >= 0.0)) return ::testing::AssertionFailure() << "tile " << t << " v " << inc.v;
    // An age is a difference of absolute times: it cannot be finer than their spacing.
    const double time_ulp = std::nextafter(std::abs(now), INFINITY) - std::abs(now);
    const struct {
      const char* name;
      double a, b, floor;
    } pairs[] = {{"v", inc.v, ref.v, 1e-9},
                 {"G_x", inc.G_x, ref.G_x, 1e-9},
                 {"G_y", inc.G_y, ref.G_y, 1e-9},
                 {"G_t", inc.G_t, ref.G_t, 1e-9},
                 {"age", inc.mean_age, ref.mean_age, 8.0 * time_ulp}};
    for (const auto& p : pairs) {
      const double tol = rel * std::abs(p.b) + p.floor;
      if (!std::isfinite(p.a) || std::abs(p.a - p.b) > tol) {
        return ::testing::AssertionFailure()
               << "tile " << t << " " << p.name << " incremental " << p.a << " brute force " << p.b;
      }
    }
    if (!std::isfinite(s.tile_error(t)) || s.tile_error(t) < 0.0) {
      return ::testing::AssertionFailure() << "tile " << t << " error " << s.tile_error(t);
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace afr::extremes
