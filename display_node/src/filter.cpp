#include <afr/display/filter.h>

#include <afr/common/error.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace afr {

const char* mode_name(ReconstructionMode mode) {
  switch (mode) {
    case ReconstructionMode::kAdaptive:
      return "adaptive";
    case ReconstructionMode::kTraditionalFrameless:
      return "frameless";
    case ReconstructionMode::kAdaptiveNoReprojection:
      return "adaptive-no-reprojection";
  }
  return "?";
}

ReconstructionMode parse_mode(std::string_view text) {
  for (ReconstructionMode m :
       {ReconstructionMode::kAdaptive, ReconstructionMode::kTraditionalFrameless,
        ReconstructionMode::kAdaptiveNoReprojection}) {
    if (text == mode_name(m)) return m;
  }
  throw Error("reconstruction mode '" + std::string(text) +
              "': expected adaptive, frameless or adaptive-no-reprojection");
}

namespace {

// v clamped to [lo, hi], NaN to lo.
double clamp_nan_low(float v, float lo, float hi) {
  return v >= lo ? std::min(double(v), double(hi)) : double(lo);
}

}  // namespace

FilterExtents filter_extents(float G_x_in, float G_y_in, float G_t_in, float R_l_in, float depth_in,
                             const FilterLimits& limits) {
  // Section 5.1: adaptive filter extents.
  // 1. Guards.
  double G_x = clamp_nan_low(G_x_in, limits.min_spatial_gradient, limits.max_spatial_gradient);
  double G_y = clamp_nan_low(G_y_in, limits.min_spatial_gradient, limits.max_spatial_gradient);
  const double G_t =
      clamp_nan_low(G_t_in, limits.min_temporal_gradient, limits.max_temporal_gradient);
  const double R_l = clamp_nan_low(R_l_in, limits.min_rate, limits.max_rate);
  const double depth = std::isnan(depth_in) ? double(limits.max_temporal_extent)
                                            : clamp_nan_low(depth_in, limits.min_temporal_extent,
                                                            limits.max_temporal_extent);
  const double lo_s = limits.min_spatial_extent, hi_s = limits.max_spatial_extent;
  const double V_s = 1.0 / R_l;
  // 2. At most max_anisotropy times longer than wide: a gradient below the floor in one
  // direction measures nothing there, it does not ask for a filter reaching the clamp.
  const double anisotropy = std::max(1.0, double(limits.max_anisotropy));
  G_x = std::max(G_x, G_y / anisotropy);
  G_y = std::max(G_y, G_x / anisotropy);

  double e_x, e_y, e_t;
  if (G_t <= double(limits.min_temporal_gradient)) {
    // 3. No measured change over time: the whole depth of the store, the volume in space.
    e_t = depth;
    const double area = V_s / e_t;
    e_x = std::clamp(std::sqrt(area * G_y / G_x), lo_s, hi_s);
    e_y = std::clamp(std::sqrt(area * G_x / G_y), lo_s, hi_s);
  } else {
    // 3. The cube roots, spatial extents clamped.
    e_x = std::clamp(std::cbrt(V_s * G_y * G_t / (G_x * G_x)), lo_s, hi_s);
    e_y = std::clamp(std::cbrt(V_s * G_x * G_t / (G_y * G_y)), lo_s, hi_s);
    // Time takes what volume is left.
    e_t = V_s / (e_x * e_y);
    // Not further back than the store reaches: the volume goes back to space.
    if (e_t > depth) {
      e_t = depth;
      const double area = V_s / e_t;
      e_x = std::clamp(std::sqrt(area * G_y / G_x), lo_s, hi_s);
      e_y = std::clamp(std::sqrt(area * G_x / G_y), lo_s, hi_s);
    }
  }
  // 4.
  e_t = std::clamp(e_t, double(limits.min_temporal_extent), double(limits.max_temporal_extent));
  return FilterExtents{float(e_x), float(e_y), float(e_t)};
}

TileFilter make_tile_filter(const FilterExtents& e, float scale_x, float scale_y) {
  TileFilter f;
  f.sigma_x = e.e_x * scale_x;
  f.sigma_y = e.e_y * scale_y;
  f.e_t = e.e_t;
  f.k_t = 0.5f / (e.e_t * e.e_t);
  return f;
}

}  // namespace afr
