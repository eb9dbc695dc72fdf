#include <afr/eval/run.h>

#include <afr/common/check.h>
#include <afr/common/clock.h>
#include <afr/common/error.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/eval/framed.h>
#include <afr/sampler/sampler.h>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

namespace afr::eval {

namespace {

using Steady = std::chrono::steady_clock;

double seconds_since(Steady::time_point start) {
  return std::chrono::duration<double>(Steady::now() - start).count();
}

int thread_count(int requested) {
  return requested > 0 ? requested : std::max(1, int(std::thread::hardware_concurrency()));
}

void validate(const RunSettings& s) {
  if (!(s.rate > 0.0 && std::isfinite(s.rate))) {
    throw Error(fmt::format("rate {} is not a positive number of rays per second", s.rate));
  }
  if (s.width < 1 || s.height < 1 || s.width > 8192 || s.height > 8192) {
    throw Error(fmt::format("image size {}x{} is outside 1..8192", s.width, s.height));
  }
  if (s.frames < 1 || !(s.fps > 0.0) || !(s.warmup >= 0.0) || !std::isfinite(s.first_time)) {
    throw Error("run: frames, fps, warmup or first time out of range");
  }
}

// The sampler and the reconstructor, joined under a virtual clock.
RunStats run_frameless(const Scene& scene, Tracer& tracer, const RunSettings& s,
                       const FrameSink& sink) {
  SamplerConfig config = s.sampler;
  config.width = s.width;
  config.height = s.height;
  config.region = PixelRect{};
  config.seed = s.seed;
  config.loop_animation = false;
  ReconstructorConfig rc = s.reconstructor;
  rc.image_width = s.width;
  rc.image_height = s.height;
  rc.threads = thread_count(s.threads);
  switch (s.method) {
    case Method::kFrameless:
      config.mode = SamplerMode::kUniformRandom;
      config.r = 0;  // no world positions: the newest sample is shown where it was taken
      rc.mode = ReconstructionMode::kTraditionalFrameless;
      break;
    case Method::kAdaptive:
      config.mode = SamplerMode::kAdaptive;
      rc.mode = ReconstructionMode::kAdaptive;
      break;
    case Method::kAdaptiveNoReprojection:
      config.mode = SamplerMode::kAdaptive;
      config.r = 0;
      rc.mode = ReconstructionMode::kAdaptiveNoReprojection;
      break;
    default:
      AFR_CHECK(false);
  }
  // The initial fill of the adaptive sampler traces a crosshair every fill_step pixels; the
  // warm-up is at least twice its virtual duration so that it is over long before frame 0.
  const double fill_rays = config.mode == SamplerMode::kAdaptive
                               ? 5.0 * std::ceil(double(s.width) / config.fill_step) *
                                     std::ceil(double(s.height) / config.fill_step)
                               : 0.0;
  const double warmup = std::max(s.warmup, 2.0 * fill_rays / s.rate);

  CpuReconstructor reconstructor(rc);
  VirtualClock clock(s.rate, s.first_time - warmup);
  RunStats stats;
  auto start = Steady::now();
  Sampler sampler(scene, tracer, clock, config, reconstructor);
  sampler.fill();

  Image image(s.width, s.height);
  SceneState state;
  // A live display reconstructs at every refresh, and its coverage map (section 6.2) adapts
  // splat sizes from one image to the next: the display also runs during the last half second
  // of the warm-up (images not compared, time not counted).
  const int warm_frames = int(std::floor(std::min(warmup, 0.5) * s.fps));
  for (int j = -warm_frames; j < 0; ++j) {
    const double t = frame_time(s, j);
    while (clock.now() < t) sampler.step();
    sampler.flush();
    stats.sample_seconds += seconds_since(start);
    scene.evaluate(t, &state);
    reconstructor.reconstruct(scene.camera_at(state), t, s.width, s.height, &image);
    start = Steady::now();
  }
  for (int j = 0; j < s.frames; ++j) {
    const double t = frame_time(s, j);
    if (j > 0 || warm_frames > 0) start = Steady::now();
    while (clock.now() < t) sampler.step();
    sampler.flush();
    stats.sample_seconds += seconds_since(start);
    start = Steady::now();
    scene.evaluate(t, &state);
    reconstructor.reconstruct(scene.camera_at(state), t, s.width, s.height, &image);
    stats.reconstruct_seconds += seconds_since(start);
    sink(j, image);
  }
  stats.primary_rays = clock.rays();
  stats.occlusion_rays = sampler.counters().occlusion_rays;
  stats.virtual_seconds = double(clock.rays()) / s.rate;
  return stats;
}

// Framed rendering, double buffered (framed.h): 60 Hz at reduced resolution, full resolution
// as fast as the rate allows, or full resolution at 60 Hz.
RunStats run_framed(const Scene& scene, Tracer& tracer, const RunSettings& s,
                    const FrameSink& sink) {
  RunStats stats;
  FrameSchedule schedule;
  schedule.origin = s.first_time;
  int w = s.width, h = s.height;
  switch (s.method) {
    case Method::kFramed60:
      framed_resolution(s.rate / s.fps, s.width, s.height, &w, &h);
      schedule.period = 1.0 / s.fps;
      break;
    case Method::kFramedFullRes:
      schedule.period = double(s.width) * double(s.height) / s.rate;
      break;
    case Method::kFullRes60:
      schedule.period = 1.0 / s.fps;
      break;
    default:
      AFR_CHECK(false);
  }
  stats.frame_width = w;
  stats.frame_height = h;
  stats.frame_period = schedule.period;
  const int threads = thread_count(s.threads);
  TraceStats ts;
  int64_t shown_k = std::numeric_limits<int64_t>::min();
  Image frame, shown;
  for (int j = 0; j < s.frames; ++j) {
    const int64_t k = schedule.frame_shown_at(frame_time(s, j));
    if (k != shown_k) {
      auto start = Steady::now();
      frame = trace_frame(tracer, schedule.input_time(k), w, h, threads, &ts);
      stats.sample_seconds += seconds_since(start);
      ++stats.frames_traced;
      start = Steady::now();
      shown = (w == s.width && h == s.height) ? frame : upsample_bilinear(frame, s.width, s.height);
      stats.reconstruct_seconds += seconds_since(start);
      shown_k = k;
    }
    sink(j, shown);
  }
  stats.primary_rays = ts.primary_rays;
  stats.shadow_rays = ts.shadow_rays;
  stats.virtual_seconds = double(stats.frames_traced) * schedule.period;
  return stats;
}

// Framed 60 Hz with temporal accumulation (taa.h), double buffered like framed 60 Hz: the
// frame shown at t_j is frame j - 1, traced with the input of t_(j-1).
RunStats run_taa(const Scene& scene, Tracer& tracer, const RunSettings& s, const FrameSink& sink) {
  RunStats stats;
  int w, h;
  framed_resolution(s.rate / s.fps, s.width, s.height, &w, &h);
  stats.frame_width = w;
  stats.frame_height = h;
  stats.frame_period = 1.0 / s.fps;
  FrameSchedule schedule{s.first_time, 1.0 / s.fps};
  TemporalAccumulator taa(s.width, s.height, w, h, s.taa);
  const int threads = thread_count(s.threads);
  TraceStats ts;
  const int64_t first_k = -int64_t(std::ceil(s.warmup * s.fps)) - 1;
  const Image* shown = nullptr;
  int64_t k = first_k;
  for (int j = 0; j < s.frames; ++j) {
    const int64_t want = schedule.frame_shown_at(frame_time(s, j));
    for (; k <= want; ++k) {
      shown = &taa.render(tracer, k, schedule.input_time(k), threads, &ts);
      ++stats.frames_traced;
    }
    sink(j, *shown);
  }
  stats.primary_rays = ts.primary_rays;
  stats.shadow_rays = ts.shadow_rays;
  stats.virtual_seconds = double(stats.frames_traced) * schedule.period;
  stats.sample_seconds = taa.trace_seconds();
  stats.reconstruct_seconds = taa.resolve_seconds();
  return stats;
}

}  // namespace

RunStats run_method(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                    const FrameSink& sink) {
  validate(settings);
  switch (settings.method) {
    case Method::kFrameless:
    case Method::kAdaptive:
    case Method::kAdaptiveNoReprojection:
      return run_frameless(scene, tracer, settings, sink);
    case Method::kFramed60:
    case Method::kFramedFullRes:
    case Method::kFullRes60:
      return run_framed(scene, tracer, settings, sink);
    case Method::kFramedTaa:
      return run_taa(scene, tracer, settings, sink);
  }
  return {};
}

}  // namespace afr::eval
