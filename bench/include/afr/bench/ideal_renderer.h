// The ideal renderer of the evaluation (paper section 7, the gold standard): every pixel of
// the image at exactly time t, with no delay, antialiased by S x S stratified jittered
// samples per pixel and a Gaussian pixel filter. Seeded: the same arguments give the same
// image bit for bit, whatever the thread count.
#pragma once

#include <afr/common/image.h>
#include <afr/common/scene.h>
#include <afr/sampler/tracer.h>

#include <cstdint>

namespace afr {

// The version of the pictures the tracer and this renderer make, part of every ideal cache key
// (bench/eval/ideal_cache.h): raise it with any change that changes an ideal image, so that a
// cache never serves images of an older renderer. 2: shadows through glass, texture filtering
// by ray cones. 3: mip levels through a binomial low-pass instead of the 2 x 2 box. 4: nested
// media (KHR_materials_volume) refract by the ratio of their iors and absorb by the innermost.
// 5: KHR_materials_diffuse_transmission. 6: generated tangent frames turn with an animated
// KHR_texture_transform. 7: shadow rays pass diffusely transmitting surfaces. 8: coinciding
// surfaces of two volumes cross from one medium into the other.
inline constexpr uint32_t kIdealRendererVersion = 8;

struct IdealRenderOptions {
  int width = 256;
  int height = 256;
  int strata = 4;     // S: S x S samples per pixel
  double time = 0.0;  // seconds
  int threads = 0;    // 0 = all cores
  uint64_t seed = 1;
  // Gaussian pixel filter exp(-alpha r^2) - exp(-alpha radius^2), separable, in pixels.
  double filter_radius = 1.0;  // >= 0.5, so every pixel weighs its own samples
  double filter_alpha = 2.0;
};

struct IdealRenderStats {
  TraceStats trace;
  double seconds = 0.0;
};

// Moves `tracer` to options.time and renders. `tracer` must be built from `scene`.
Image render_ideal(Tracer& tracer, const IdealRenderOptions& options,
                   IdealRenderStats* stats = nullptr);

}  // namespace afr
