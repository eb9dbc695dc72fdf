// One run of one method: the method renders the frames shown at display times
// first_time + j / fps (j = 0 .. frames - 1) at a simulated rate of R primary rays per second.
// Frameless methods run the real sampler and reconstructor libraries in this process under a
// VirtualClock (time advances 1/R per primary ray); framed methods trace whole frames with the
// same tracer and count their primary rays the same way. Occlusion rays of the sampler's
// reprojection are counted apart and do not advance the clock (the paper's rates count
// primary rays only).
#pragma once

#include <afr/common/image.h>
#include <afr/common/scene.h>
#include <afr/display/reconstructor.h>
#include <afr/eval/methods.h>
#include <afr/eval/taa.h>
#include <afr/sampler/sampler_config.h>
#include <afr/sampler/tracer.h>

#include <functional>

namespace afr::eval {

struct RunSettings {
  Method method = Method::kAdaptive;
  double rate = 400000.0;  // primary rays per second (ignored by full-res 60 Hz)
  int width = 256;
  int height = 256;
  double first_time = 0.0;  // display time of frame 0, seconds (scene time)
  int frames = 60;
  double fps = 60.0;
  // Virtual seconds the frameless samplers and TAA run before frame 0, so that deep buffers
  // and histories are full when the comparison starts (framed renderers have run for ever).
  double warmup = 1.0;
  // Knobs of the adaptive sampler (mode, size, r for the no-reprojection method, seed and
  // animation looping are set by the run).
  SamplerConfig sampler;
  // Reconstructor settings (image size and mode are set by the run).
  ReconstructorConfig reconstructor;
  TaaOptions taa;
  uint64_t seed = 1;
  int threads = 0;  // tracing threads of framed methods and reconstructor threads; 0 = all
};

struct RunStats {
  uint64_t primary_rays = 0;         // what the rate counts
  uint64_t occlusion_rays = 0;       // sampler reprojection's visibility tests, apart
  uint64_t shadow_rays = 0;          // shading's rays, for the record
  double virtual_seconds = 0.0;      // of sampling: primary_rays / R for frameless methods
  double sample_seconds = 0.0;       // wall time tracing and controlling (sampler or frames)
  double reconstruct_seconds = 0.0;  // wall time making images (reconstructor, upsampling, TAA)
  int frame_width = 0;               // framed methods: the resolution of a frame
  int frame_height = 0;
  double frame_period = 0.0;   // framed methods: seconds per frame
  uint64_t frames_traced = 0;  // framed methods: frames traced
};

// Called with each frame index j and its image (width x height), in order.
using FrameSink = std::function<void(int j, const Image& image)>;

// Runs settings.method on `scene` (finalized) with `tracer` (built from it). The tracer's
// time is changed. Throws afr::Error for settings out of range.
RunStats run_method(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                    const FrameSink& sink);

// The display time of frame j.
inline double frame_time(const RunSettings& s, int j) { return s.first_time + double(j) / s.fps; }

}  // namespace afr::eval
