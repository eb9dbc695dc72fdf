// The gold standard of section 7, cached: ideal frames (zero delay, antialiased) from
// render_ideal, stored on disk as linear float EXR under a key made of everything that changes
// them, so that every method, rate and later run compares against the same images and renders
// each ideal frame once.
#pragma once

#include <afr/bench/ideal_renderer.h>
#include <afr/common/image.h>
#include <afr/sampler/tracer.h>

#include <cstdint>
#include <filesystem>
#include <string>

namespace afr::eval {

// The cache key of one ideal frame: the scene's render_fingerprint, the frame's size, samples
// per pixel and time, and a hash of the remaining render options (seed, pixel filter) and of
// the tracer's options. The text is a file name:
//   <scene hash, 16 hex>-<W>x<H>-spp<S*S>-t<time>-o<options hash, 8 hex>
// with the time written so that it reads back as the same double.
std::string ideal_cache_key(uint64_t fingerprint, const IdealRenderOptions& options,
                            const TracerOptions& tracer_options);

struct IdealCacheStats {
  uint64_t hits = 0;
  uint64_t misses = 0;          // rendered (and stored)
  double render_seconds = 0.0;  // wall time spent rendering
};

class IdealCache {
 public:
  // `folder` is created when the first frame is stored. `fingerprint` (render_fingerprint)
  // identifies the scene the tracers given to frame() were built from.
  IdealCache(std::filesystem::path folder, uint64_t fingerprint);

  // The ideal frame for `options` (its time, size, strata, seed, filter): read from the cache,
  // or rendered with `tracer` and stored (written to a temporary name, then renamed, so a
  // crash never leaves a partial file under a key). A cached file of the wrong size is
  // rendered again.
  Image frame(Tracer& tracer, const IdealRenderOptions& options);
  std::filesystem::path path_of(const IdealRenderOptions& options,
                                const TracerOptions& tracer_options) const;

  const IdealCacheStats& stats() const { return stats_; }

 private:
  std::filesystem::path folder_;
  uint64_t fingerprint_;
  IdealCacheStats stats_;
};

}  // namespace afr::eval
