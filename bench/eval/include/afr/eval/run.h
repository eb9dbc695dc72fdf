// One run of one method: the method renders the frames shown at display times
// t_j = first_time + j / fps (j = 0 .. frames - 1) with a budget of R rays per second.
// Frameless methods run the real sampler and reconstructor libraries in this process under a
// BudgetClock (time advances 1/R per primary ray and occlusion_ray_cost / R per occlusion ray
// of the sampler's reprojection); framed methods trace whole frames with the same tracer and
// count their rays the same way.
//
// One display rule for every method (docs/evaluation.md, "What is compared"): the image shown
// at t_j is made from input (camera, scene time, samples) no newer than t_j - latency, and no
// newer than the method's own pipeline allows: a framed renderer shows a frame only once its
// rays are traced, a frame period after the input it was started with.
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
  // Seconds between the input an image is made from and the display time it is shown at:
  // the display stage of the pipeline (a reconstruction that takes a refresh: 1 / fps). 0 is
  // the former accounting, where the frameless methods showed at t_j an image made from the
  // samples and camera of t_j itself.
  double latency = 1.0 / 60.0;
  // Rays charged to the budget per occlusion ray of the sampler (1: one ray; 0: free, the
  // former accounting).
  double occlusion_ray_cost = 1.0;
  // Virtual seconds the frameless samplers and TAA run before frame 0, so that deep buffers
  // and histories are full when the comparison starts (framed renderers have run for ever).
  double warmup = 1.0;
  // Knobs of the adaptive sampler (mode, size, r for the no-reprojection method, seed and
  // animation looping are set by the run).
  SamplerConfig sampler;
  // Reconstructor settings (image size and mode are set by the run).
  ReconstructorConfig reconstructor;
  TaaOptions taa;
  // The sampler's seed; for framed full res also the phase of its frame schedule and for TAA
  // the start of its jitter sequence (seed 1: phase 0, sequence from its start). Framed 60 Hz
  // and full res 60 Hz do not depend on it (method_uses_seed).
  uint64_t seed = 1;
  int threads = 0;  // tracing threads of framed methods and reconstructor threads; 0 = all
};

struct RunStats {
  uint64_t primary_rays = 0;         // traced primary rays
  uint64_t occlusion_rays = 0;       // sampler reprojection's visibility tests
  uint64_t shadow_rays = 0;          // shading's rays, part of a shaded ray's cost, not counted
  double charged_rays = 0.0;         // what the budget paid: primary + cost x occlusion
  double virtual_seconds = 0.0;      // of sampling: charged_rays / R
  double sample_seconds = 0.0;       // wall time tracing and controlling (sampler or frames)
  double reconstruct_seconds = 0.0;  // wall time making images (reconstructor, upsampling, TAA)
  int frame_width = 0;               // framed methods: the resolution of a frame
  int frame_height = 0;
  double frame_period = 0.0;   // framed methods: seconds per frame
  uint64_t frames_traced = 0;  // framed methods: frames traced
};

// What the image shown at t_j was made from.
struct FrameInput {
  // The scene time and camera the image was made with (reconstruction, or the frame's
  // trace; TAA: the newest frame accumulated).
  double input_time = 0.0;
  // The newest sample time in it: frameless methods, the newest sample that had reached the
  // reconstructor; framed methods, input_time.
  double newest_sample = 0.0;
};

// Called with each frame index j, its image (width x height) and its input, in order.
using FrameSink = std::function<void(int j, const Image& image, const FrameInput& input)>;

// Runs settings.method on `scene` (finalized) with `tracer` (built from it). The tracer's
// time is changed. Throws afr::Error for settings out of range.
RunStats run_method(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                    const FrameSink& sink);

// The display time of frame j.
inline double frame_time(const RunSettings& s, int j) { return s.first_time + double(j) / s.fps; }

// The newest input the display stage may use for frame j: t_j - latency.
inline double input_time(const RunSettings& s, int j) { return frame_time(s, j) - s.latency; }

// The phase, in frame periods, of framed full res's schedule for a seed: 0 for seed 1, then
// the golden-ratio sequence (0.618, 0.236, 0.854, ...), so that seeds spread over [0, 1).
double schedule_phase(uint64_t seed);

}  // namespace afr::eval
