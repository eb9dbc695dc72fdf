// Shared pieces of the numerical-extremes tests: checks that every value a part hands on is
// finite, and an independent, brute-force recomputation of a sampler tile's statistics from
// its deep buffer (the definitions of section 4, in long double).
#pragma once

#include <afr/common/samples.h>
#include <afr/sampler/sampler.h>
#include "support/tile_stats.h"

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

// Every tile's incremental statistics equal the brute-force ones (relative tolerance `rel`,
// with an absolute floor of 1e-9 luminance units, far below any step of a display, for values
// near zero), and the variance is never negative. `luminance_scale` is the brightest sample's
// luminance where it is far above 1: a variance cannot be resolved finer than the rounding of
// its square (a tile of samples all at 65504 has variance 0, which a sum of squares of about
// 4e9 in doubles gives as 1e-9), nor a gradient finer than the rounding of it.
inline ::testing::AssertionResult stats_match_buffer(const Sampler& s, double now,
                                                     double rel = 1e-6,
                                                     double luminance_scale = 1.0) {
  const double m = std::max(1.0, luminance_scale);
  const double v_floor = 1e-9 + 64.0 * std::numeric_limits<double>::epsilon() * m * m;
  const double g_floor = 1e-9 + 64.0 * std::numeric_limits<double>::epsilon() * m;
  for (int t : s.tiling().tiles()) {
    const TileStats inc = s.tile_stats(t);
    const TileStats ref = testing::brute_force_stats(s, t, now);
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
    } pairs[] = {{"v", inc.v, ref.v, v_floor},
                 {"G_x", inc.G_x, ref.G_x, g_floor},
                 {"G_y", inc.G_y, ref.G_y, g_floor},
                 {"G_t", inc.G_t, ref.G_t, g_floor},
                 {"age", inc.mean_age, ref.mean_age, 8.0 * time_ulp},
                 {"occluded", inc.occluded, ref.occluded, 1e-9}};
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
