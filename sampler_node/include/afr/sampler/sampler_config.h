// Every knob of the sampler, with the defaults afr uses and the ranges it accepts.
#pragma once

#include <afr/common/presets.h>
#include <afr/sampler/tiling.h>

#include <cstdint>
#include <string>

namespace afr {

enum class SamplerMode {
  kAdaptive,       // afr: the closed loop of Figure 5
  kUniformRandom,  // traditional frameless [BFMS94]: uniformly random pixels
  kFramedSweep,    // every pixel center of the region in scanline order, over and over
};

// How reprojection (section 6.1) moves a crosshair's points on a rigidly moving object
// (docs/sampler.md, "Moving points").
enum class CrosshairMotion {
  // Along the center's velocity over the crosshair's age, as the display moves the samples it
  // shows (display_node reprojection.h): a crosshair lands where the display puts its sample,
  // so its temporal gradient measures the error the display makes there.
  kVelocity,
  // By the object's transform at the new time: exact (a turning object's points stay on it),
  // but blind to where a display that extrapolates velocities goes wrong.
  kTransform,
};

struct SamplerConfig {
  SamplerMode mode = SamplerMode::kAdaptive;
  ImageExtent image{256, 256};  // the whole image
  PixelRect region;             // the part this sampler owns; empty = the whole image
  uint32_t sampler_id = 0;
  uint64_t seed = 1;

  int b = 4;       // deep buffer depth (section 4)
  int r = 5;       // reprojections per tile visit (section 6.1); 0 = no reprojection
  int chunk = 25;  // crosshairs between tiling adjustments (section 4.2)
  // Error weights of section 6.1: kappa (variance), lambda (undersampling), the rest occlusion.
  // kappa, lambda, m and i were chosen with afr-eval --sweep --knobs kappa,lambda,m,i, and
  // lambda 0.4 (occlusion none) over whole animations (docs/sampler.md, "The occlusion term").
  double kappa = 0.6;
  double lambda = 0.4;
  double m = 1.0;  // undersampling threshold (section 6.1)
  // Importance of temporal against spatial change in gain control (section 4.1). With i = 1
  // the built-in scene's moving camera drives the count to min_tiles (afr-sample --i 1).
  double i = 0.1;
  // Gain control's tile count bounds; the count never exceeds the region's pixels / 4.
  int min_tiles = 16;
  int max_tiles = 1024;
  int max_tiling_ops = 2;  // splits plus merges per adjustment
  bool occlusion_rays = true;
  CrosshairMotion crosshair_motion = CrosshairMotion::kVelocity;
  // The scene's animation repeats over its keyframe range while the clock runs on.
  bool loop_animation = true;

  double refresh_interval = 1.0 / 60.0;  // seconds between tiling snapshots
  double animation_step = 1e-3;          // the tracer's scene time follows the clock in these steps
  int fill_step = 2;     // initial fill: one crosshair every fill_step pixels in x and y
  int batch_size = 128;  // samples per emitted batch

  // The region actually owned (`region`, or the whole image when it is empty).
  PixelRect owned_region() const;
  // Throws afr::Error naming the first field out of range.
  void validate() const;
};

// A preset's sampler knobs (afr/common/presets.h) set in `config`; the rest is left as it is.
inline void apply_preset(const Preset& preset, SamplerConfig* config) {
  config->b = preset.b;
  config->r = preset.r;
  config->chunk = preset.chunk;
  config->min_tiles = preset.min_tiles;
  config->max_tiles = preset.max_tiles;
}

}  // namespace afr
