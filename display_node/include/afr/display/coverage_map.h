// Section 6.2: the coverage map. Every splat of an image adds to the pixels it reaches; the
// next image sizes each splat from the count and mean splat growth at its pixel, so splats
// grow fast where samples are sparse (disocclusions, leading edges) and shrink gradually where
// they pile up.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace afr {

// One pixel of the map, as accumulated during an image: how many splats reached it with a
// non-zero weight and the sum of their growths (a splat's radius over its filter's radius
// cutoff max(sigma_x, sigma_y); mean = growth_sum / count).
struct CoverageCell {
  float count = 0.0f;
  float growth_sum = 0.0f;
};

// The resizing rule and its bounds (radii in output pixels). A pixel reached by between
// grow_below and shrink_above splats is sampled well; fewer: its splats grow, more: they
// shrink, each image by the factor that would bring the count into the band if the count
// grows with the splats' area (count ~ r^2), within [shrink, grow]. Growing goes there at once,
// shrinking half way (in log) per image: fast where undersampled, gradual where oversampled.
// `shrink` bounds only gross oversampling (over 32 / shrink^4 splats a pixel: 8192 at 0.25):
// the store's density jumps when a sampler's first fill lands, and wide splats grown while it
// was sparse would cost seconds of reconstruction; the floor lets them come down within two
// or three images, splat_density_cap (below) bounds them from the first.
// Every image also pulls the growth a fraction `relax` of the way back to 1 (the filter's own
// size), so that the map has one fixed point for a given sample density, whatever the history.
struct SplatSizeRule {
  float grow_below = 4.0f;     // fewer samples than this reached the pixel: undersampled
  float grow = 4.0f;           // the most a splat grows per image (and a hole's growth)
  float shrink_above = 32.0f;  // more than this: oversampled
  float shrink = 0.25f;        // the most it shrinks per image
  float relax = 0.05f;         // per image, toward growth 1
  float min_radius = 1.0f;     // a splat always reaches the pixel it falls in
  float max_radius = 32.0f;    // bounds cost; GL point sprites are 2 r + 1 <= 65 pixels
  // The former rule, kept as the baseline of docs/reconstruction.md's comparison (afr-eval
  // --coverage-rule thresholds; the CPU backend only): the mean growth times `grow` below the
  // band, times `shrink` above it (0.7 then), as it is inside; no pull toward 1.
  bool thresholds = false;
};

// Reconstructors clamp SplatSizeRule::max_radius to this: llvmpipe's largest point sprite is
// 255 pixels, and a splat of radius r is drawn as a 2 r + 1 pixel sprite.
inline constexpr float kSplatRadiusLimit = 120.0f;

// Samples whose center is within this many pixels outside the image are splatted (their
// splat may reach it); others are off-screen.
inline int splat_guard_band(const SplatSizeRule& rule) {
  return int(std::ceil(rule.max_radius)) + 1;
}

// Section 6.2: the radius of a splat whose filter wants `filter_radius` (cutoff sigmas), given
// the previous image's cell at its pixel (nullptr when there is no previous image). The map
// holds growths, radii relative to their own filter's, not radii: a splat takes the mean
// growth m of the splats that reached its pixel, pulled toward 1, times a factor of the count
// c:
//   no previous image       -> g = 1
//   c = 0 (a hole)          -> g = grow
//   c < grow_below          -> g = b min(grow, sqrt(grow_below / c))
//   c > shrink_above        -> g = b max(shrink, sqrt(sqrt(shrink_above / c)))
//   otherwise               -> g = b,        with b = m + relax (1 - m)
// and r = g * filter_radius, clamped to [min_radius, max_radius]; NaN or non-positive input
// gives min_radius. The factor is continuous in c (1 at both ends of the band), so a count
// one splat higher or lower moves a growth a little, not 4x: the map converges to one state
// for a given sample density instead of amplifying rounding differences image after image
// (docs/reconstruction.md, "Coverage map"). (Averaging absolute radii, as the paper words it,
// lets the wide splats of a sparse region set the size of the narrow ones of a dense region
// next to it, which then reach further and blur across edges.)
inline float splat_radius(const CoverageCell* previous, float filter_radius,
                          const SplatSizeRule& rule) {
  float g = 1.0f;
  if (previous != nullptr) {
    const float c = previous->count;
    if (!(c > 0.0f)) {
      g = rule.grow;
    } else {
      const float mean = previous->growth_sum / c;
      const float base = mean + rule.relax * (1.0f - mean);
      if (rule.thresholds) {
        g = c < rule.grow_below     ? rule.grow * mean
            : c > rule.shrink_above ? rule.shrink * mean
                                    : mean;
      } else if (c < rule.grow_below) {
        g = base * std::fmin(rule.grow, std::sqrt(rule.grow_below / c));
      } else if (c > rule.shrink_above) {
        g = base * std::fmax(rule.shrink, std::sqrt(std::sqrt(rule.shrink_above / c)));
      } else {
        g = base;
      }
    }
  }
  const float r = g * filter_radius;
  if (!(r >= rule.min_radius)) return rule.min_radius;  // NaN too
  return r < rule.max_radius ? r : rule.max_radius;
}

// The widest splat a tile's stored density calls for: at `density` samples per output pixel, a
// splat of radius r is reached by about density (2 r)^2 others, and none needs more than 4 x
// shrink_above of them. The map sizes splats from the last image's counts; when the store's
// density jumped since (a sampler's first fill), they would be that many times too wide, and an
// image's cost grows with their area. The largest float (no cap) where the density is not
// positive.
inline float splat_density_cap(float density, const SplatSizeRule& rule) {
  if (!(density > 0.0f)) return std::numeric_limits<float>::max();
  return 0.5f * std::sqrt(4.0f * rule.shrink_above / density);
}

// What a splat of radius r records in the map: its growth r / filter_radius.
inline float splat_growth(float radius, float filter_radius) { return radius / filter_radius; }

// The previous image's map, held by the CPU backend (the GL backend keeps it in a texture).
class CoverageMap {
 public:
  // Drops the map (no previous image) and sets the size of the next one.
  void reset(int width, int height);
  int width() const { return width_; }
  int height() const { return height_; }
  bool valid() const { return valid_; }
  void set_valid(bool valid) { valid_ = valid; }
  std::vector<CoverageCell>& cells() { return cells_; }
  const std::vector<CoverageCell>& cells() const { return cells_; }
  const CoverageCell* at(int x, int y) const {
    return valid_ ? &cells_[std::size_t(y) * std::size_t(width_) + std::size_t(x)] : nullptr;
  }

 private:
  int width_ = 0;
  int height_ = 0;
  bool valid_ = false;
  std::vector<CoverageCell> cells_;
};

}  // namespace afr
