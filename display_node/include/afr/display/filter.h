// Section 5.1: the adaptive space-time filter. From the local gradients G_x, G_y, G_t and the
// local sampling rate R_l of the tile field, a Gaussian whose standard deviations e_x, e_y
// (pixels) and e_t (seconds) span equal expected color change in each dimension while its
// space-time volume is the volume V_s = 1 / R_l that one sample occupies.
#pragma once

#include <string_view>

namespace afr {

// The reconstruction methods of the evaluation (paper, Table 1 and Figure 6).
enum class ReconstructionMode {
  kAdaptive,                // space-time filter of this file, samples reprojected (6.2)
  kTraditionalFrameless,    // the newest sample at each pixel [BFMS94], no filter
  kAdaptiveNoReprojection,  // the adaptive filter at the samples' original image positions
};
const char* mode_name(ReconstructionMode mode);
// "adaptive", "frameless", "adaptive-no-reprojection"; throws afr::Error naming the text.
ReconstructionMode parse_mode(std::string_view text);

// Every guard and clamp of the filter. Units: luminance per pixel, luminance per second,
// samples per pixel per second, pixels and seconds (pixels of the sampling image).
struct FilterLimits {
  // Gradients below these (including zero, negative and NaN) are raised to them, so every
  // ratio of gradients is finite: a dimension with no measured change gets a wide extent
  // (up to its clamp) instead of an infinite one.
  float min_spatial_gradient = 1e-4f;
  float min_temporal_gradient = 1e-4f;
  // ... and those above these (including infinity) lowered to them.
  float max_spatial_gradient = 1e6f;
  float max_temporal_gradient = 1e6f;
  // R_l is clamped to this range (NaN, zero and negative rates to min_rate).
  float min_rate = 1e-3f;
  float max_rate = 1e7f;
  // Spatial standard deviations, pixels. 0.3 keeps at least a few samples under a splat at
  // the densest sampling the store holds; 4 bounds blur and splat cost (Table 1's adaptive
  // cells are lower or level with 4 than with 16: bench/results/filter-extent.md).
  float min_spatial_extent = 0.3f;
  float max_spatial_extent = 4.0f;
  // The larger spatial extent is at most this many times the smaller (the smaller spatial
  // gradient is raised to 1 / max_anisotropy of the larger).
  float max_anisotropy = 4.0f;
  // Temporal standard deviation, seconds.
  float min_temporal_extent = 1e-3f;
  float max_temporal_extent = 60.0f;
  // A splat ends at `cutoff` standard deviations (before the coverage map resizes it).
  float cutoff = 3.0f;
  // No sample gets a temporal weight below this: a pixel that only old samples reach still
  // shows them, but any recent sample that reaches it outweighs them by ~1e12.
  float min_temporal_weight = 1e-12f;
  // Samples stamped further than this in the future of the reconstruction time (a sampler
  // with a broken clock) are skipped; nearer ones count as age 0.
  float max_future = 1.0f;
};

// Standard deviations of the space-time Gaussian, in pixels of the sampling image and seconds.
struct FilterExtents {
  float e_x = 0.0f;
  float e_y = 0.0f;
  float e_t = 0.0f;
};

// Section 5.1: e_x G_x = e_y G_y = e_t G_t and e_x e_y e_t = V_s = 1 / R_l, that is
//   e_x = cbrt(V_s G_y G_t / G_x^2),  e_y = cbrt(V_s G_x G_t / G_y^2),  e_t = V_s / (e_x e_y).
// Guarded and clamped, in this order:
//   1. gradients clamped to [min, max] (NaN to min), R_l clamped, `depth` clamped to the
//      temporal range (NaN to its top);
//   2. the smaller spatial gradient raised to 1 / max_anisotropy of the larger;
//   3. G_t at its floor (no measured change over time, a still region): e_t = depth and the
//      volume goes to space, e_x e_y = V_s / depth with e_x / e_y = G_y / G_x, clamped.
//      Otherwise: e_x, e_y from the cube roots, clamped to [min_spatial_extent,
//      max_spatial_extent]; e_t = V_s / (e_x e_y), so the volume survives the spatial clamp;
//      if e_t exceeds `depth` (how far back the sample store reaches), e_t = depth and the
//      volume goes back to space as in the still case;
//   4. e_t clamped to [min_temporal_extent, max_temporal_extent].
// Without clamps (max_anisotropy infinite) this is exactly the paper's three cube roots. Step
// 3's first branch is their limit for G_t -> 0; taking the floors as gradients instead traded
// pixels for seconds one to one wherever a spatial gradient was at its floor too (a straight
// edge): a still edge got e_t ~ 10 ms of a 0.65 s store. The result is always finite and
// inside the documented ranges.
FilterExtents filter_extents(float G_x, float G_y, float G_t, float R_l, float depth,
                             const FilterLimits& limits);

// What a splat needs from its tile, in output pixels (the extents times the output scale).
struct TileFilter {
  float sigma_x = 1.0f;  // output pixels
  float sigma_y = 1.0f;
  float k_t = 0.0f;  // 1 / (2 e_t^2): the temporal weight is exp(-age^2 k_t)
  float e_t = 1.0f;  // seconds
};
TileFilter make_tile_filter(const FilterExtents& e, float scale_x, float scale_y);

// A splat's contribution to a pixel at offset (dx, dy) from it, with weight w_t in time, is
//   w = (exp(-dx^2 k_x) - exp(-r_x^2 k_x)) (exp(-dy^2 k_y) - exp(-r_y^2 k_y)) w_t
// for |dx| < r_x and |dy| < r_y, with k = 1 / (2 sigma^2): a Gaussian lowered by its value at
// the splat's edge, so it falls to exactly 0 there and pixels on the edge matter nothing.
// The filter's radius is r_f = cutoff max(sigma_x, sigma_y); the coverage map sets the splat
// size r (coverage_map.h); when r > r_f both sigmas are multiplied by r / r_f, so a grown
// splat keeps its shape and still reaches its edge. The splat is the square of radius r cut
// to the Gaussian's cutoff box: r_x = min(r, cutoff sigma_x), r_y likewise.
// w_t = max(exp(-age^2 k_t), min_temporal_weight) / (sigma_x sigma_y): every splat carries the
// same total weight, so a wide splat from a sparse region, reaching into a dense one, weighs
// little there against the narrow splats of the samples next to the pixel (unnormalised, its
// peak weighed as much as theirs and the colors of flat regions bled pixels across edges).
// Contributions at or below this weight are dropped (they would be denormal in the sums).
inline constexpr float kMinSplatWeight = 1e-30f;

}  // namespace afr
