// The gold-standard evaluation of section 7: for each animation, ideal frames at 60 Hz (cached,
// ideal_cache.h), then every method at every rate (run.h), each frame compared with the ideal
// frame of the same display time by RMS error on the 0-255 scale. Results feed the tables,
// plots and image strips of report.h.
#pragma once

#include <afr/eval/animations.h>
#include <afr/eval/methods.h>
#include <afr/eval/progress.h>
#include <afr/eval/run.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace afr::eval {

struct EvalConfig {
  std::vector<AnimationSpec> animations;
  std::vector<double> rates{1e5, 4e5, 8e5};
  std::vector<Method> methods;  // empty: all
  double seconds = 2.0;         // of animation evaluated per run (frames = seconds x fps)
  int ideal_spp = 16;           // a square
  std::filesystem::path cache;  // ideal frames; empty: no cache
  // Frame indices kept for the image strips (clamped to the run's frames).
  std::vector<int> strip_frames;
  // Everything else of a run: size, fps, latency, occlusion ray cost, warm-up, knobs, first
  // seed, threads (method, rate, seed, first_time and frames are set per run).
  RunSettings base;
  // Runs per (method, rate) with seeds base.seed, base.seed + 1, ...: the tables give their
  // mean and range. Methods no seed changes (method_uses_seed) run once.
  int seeds = 3;
  // Runs of an animation done at the same time, each with base.threads / jobs threads (at
  // least 1); 0: one per core. Results do not depend on it (each run has its own sampler,
  // reconstructor and seed, and the CPU reconstructor's image does not depend on its thread
  // count); wall times per run do (a run gets fewer cores).
  int jobs = 1;
  bool progress = true;
};

// How evaluate() splits the cores: runs at a time, and threads per run.
struct JobSplit {
  int jobs = 1;
  int threads_per_run = 1;
};
JobSplit job_split(const EvalConfig& config);
// The options of every tracer of a split: Embree builds and commits with the threads of one
// run (TracerOptions::embree_threads), so that a run's scene-time moves keep to its share of
// the cores.
TracerOptions tracer_options(const JobSplit& split);

struct RunResult {
  std::string animation;
  Method method = Method::kAdaptive;
  double rate = 0.0;  // the R of the run (W x H x fps for full-res 60 Hz)
  uint64_t seed = 1;
  RunStats stats;
  std::vector<double> frame_times;
  std::vector<FrameInput> inputs;  // per frame: what its image was made from
  std::vector<double> rms;         // per frame
  double mean_rms = 0.0;
  std::map<int, Image> strip_images;  // frame index -> image, for strip_frames
};

struct AnimationResult {
  AnimationSpec spec;
  std::vector<double> frame_times;
  std::map<int, Image> ideal_strip_images;
  std::vector<RunResult> runs;
  double ideal_seconds = 0.0;  // wall time rendering ideal frames (0 when all were cached)
  uint64_t ideal_cached = 0, ideal_rendered = 0;
  // The scene's animation ends at duration seconds (0: it does not move); still_frames of
  // the window's frames come after that and show its last pose, a still scene.
  double duration = 0.0;
  int still_frames = 0;
};

// Loads an animation's scene and applies its camera path. Throws afr::Error naming the file.
Scene load_animation_scene(const AnimationSpec& spec);

// The ideal frames of an animation: frames x (first_time + j / fps), from the cache or
// rendered (and cached) with ideal_spp samples per pixel.
std::vector<Image> ideal_frames(const Scene& scene, Tracer& tracer, const EvalConfig& config,
                                double first_time, int frames, Progress* progress,
                                AnimationResult* result);

// Runs every (method, rate, seed) of `config` on every animation. The full-res 60 Hz
// reference runs once per animation and seed (its rate is fixed). Runs are in table order,
// the seeds of one (method, rate) after each other.
std::vector<AnimationResult> evaluate(const EvalConfig& config);

// Runs `runs` (all of one animation, compared with its `ideal` frames) `jobs` at a time, each
// on its own tracer, the highest rates first; the results are in the order of `runs`. The runs
// with seed `strip_seed` keep the images of `strips`. Rethrows the first run's error after
// every worker has stopped.
std::vector<RunResult> run_all(const Scene& scene, Tracer& tracer,
                               const std::vector<RunSettings>& runs,
                               const std::vector<Image>& ideal, int jobs,
                               const std::string& animation, const std::vector<int>& strips,
                               uint64_t strip_seed, Progress* progress);

// Renders (or finds in the cache) the ideal frames of every animation and nothing else: a
// cold cache made warm before a timed run.
void render_ideal_only(const EvalConfig& config);

// One run, compared with ideal frames (the frames of `settings`). Keeps the images of
// `strip_frames`.
RunResult run_and_compare(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                          const std::vector<Image>& ideal, const std::vector<int>& strip_frames,
                          Progress* progress);

}  // namespace afr::eval
