#include <afr/eval/run.h>

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/eval/framed.h>
#include <afr/eval/ray_budget.h>
#include <afr/sampler/sampler.h>

#include <fmt/format.h>

#include <algorithm>
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
  if (!(s.latency >= 0.0 && s.latency <= 60.0)) {
    throw Error(fmt::format("latency {} s is outside 0..60 s", s.latency));
  }
  if (!(s.occlusion_ray_cost >= 0.0 && s.occlusion_ray_cost <= 1000.0)) {
    throw Error(fmt::format("occlusion ray cost {} is outside 0..1000 rays", s.occlusion_ray_cost));
  }
}

// Between the sampler and the reconstructor: passes everything on and keeps the time of the
// newest sample passed, which is what the next image can show.
class NewestSampleSink final : public SampleSink {
 public:
  explicit NewestSampleSink(SampleSink& next) : next_(next) {}
  // The input time of the image being made: samples newer than it are held back until an
  // image whose input time reaches them. A sampler's last step before the input time can
  // trace past it (its reprojections move the scene's time on within the step).
  void set_input_time(double t) {
    limit_ = t;
    if (held_.samples.empty()) return;
    SampleBatch ready;
    ready.sampler_id = held_.sampler_id;
    ready.fields = held_.fields;
    std::vector<Sample> later;
    for (const Sample& sample : held_.samples)
      (sample.time <= t ? ready.samples : later).push_back(sample);
    held_.samples = std::move(later);
    if (!ready.samples.empty()) pass_on(std::move(ready));
  }
  void on_batch(SampleBatch&& batch) override {
    const auto newer = [&](const Sample& sample) { return sample.time > limit_; };
    if (std::any_of(batch.samples.begin(), batch.samples.end(), newer)) {
      if (held_.samples.empty()) {
        held_.sampler_id = batch.sampler_id;
        held_.fields = batch.fields;
      }
      for (const Sample& sample : batch.samples)
        if (newer(sample)) held_.samples.push_back(sample);
      batch.samples.erase(std::remove_if(batch.samples.begin(), batch.samples.end(), newer),
                          batch.samples.end());
    }
    if (!batch.samples.empty()) pass_on(std::move(batch));
  }
  void on_tiling(TilingSnapshot&& snapshot) override { next_.on_tiling(std::move(snapshot)); }
  double newest() const { return newest_; }

 private:
  void pass_on(SampleBatch&& batch) {
    for (const Sample& sample : batch.samples) newest_ = std::max(newest_, sample.time);
    next_.on_batch(std::move(batch));
  }

  SampleSink& next_;
  double limit_ = std::numeric_limits<double>::infinity();
  SampleBatch held_;
  double newest_ = -std::numeric_limits<double>::infinity();
};

// The sampler and the reconstructor, joined under a virtual clock.
RunStats run_frameless(const Scene& scene, Tracer& tracer, const RunSettings& s,
                       const FrameSink& sink) {
  SamplerConfig config = s.sampler;
  config.image = ImageExtent{s.width, s.height};
  config.region = PixelRect{};
  config.seed = s.seed;
  config.loop_animation = false;
  ReconstructorConfig rc = s.reconstructor;
  rc.image = ImageExtent{s.width, s.height};
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
  NewestSampleSink sink_to_display(reconstructor);
  // The sampler runs from `warmup` before the first image's input time, so that the first
  // compared image has the same history at every latency.
  BudgetClock clock(s.rate, input_time(s, 0) - warmup, s.occlusion_ray_cost);
  RunStats stats;
  auto start = Steady::now();
  Sampler sampler(scene, tracer, clock, config, sink_to_display);
  sampler.fill();

  Image image(s.width, s.height);
  SceneState state;
  // The display stage of frame j: the samples traced until t_in = t_j - latency and the
  // camera of t_in make the image shown at t_j; the sampler traces on meanwhile (frame j + 1
  // takes the samples up to its own t_in).
  const auto make_image = [&](int j) {
    const double t_in = input_time(s, j);
    sink_to_display.set_input_time(t_in);
    sample_until(sampler, clock, t_in);
    sampler.flush();
    stats.sample_seconds += seconds_since(start);
    start = Steady::now();
    scene.evaluate(t_in, &state);
    reconstructor.reconstruct(scene.camera_at(state), t_in, s.width, s.height, &image);
    return FrameInput{t_in, sink_to_display.newest()};
  };
  // A live display reconstructs at every refresh, and its coverage map (section 6.2) adapts
  // splat sizes from one image to the next: the display also runs during the last half second
  // of the warm-up (images not compared, time not counted).
  const int warm_frames = int(std::floor(std::min(warmup, 0.5) * s.fps));
  for (int j = -warm_frames; j < 0; ++j) {
    make_image(j);
    start = Steady::now();
  }
  for (int j = 0; j < s.frames; ++j) {
    const FrameInput input = make_image(j);
    stats.reconstruct_seconds += seconds_since(start);
    sink(j, image, input);
    start = Steady::now();
  }
  stats.primary_rays = clock.primary_rays();
  stats.occlusion_rays = clock.occlusion_rays();
  stats.charged_rays = clock.charged_rays();
  stats.virtual_seconds = clock.charged_rays() / s.rate;
  return stats;
}

// Framed rendering, double buffered (framed.h): 60 Hz at reduced resolution, full resolution
// as fast as the rate allows, or full resolution at 60 Hz.
RunStats run_framed(const Scene& scene, Tracer& tracer, const RunSettings& s,
                    const FrameSink& sink) {
  RunStats stats;
  FrameSchedule schedule;
  schedule.origin = s.first_time;
  schedule.latency = s.latency;
  int w = s.width, h = s.height;
  switch (s.method) {
    case Method::kFramed60:
      framed_resolution(s.rate / s.fps, s.width, s.height, &w, &h);
      schedule.period = 1.0 / s.fps;
      break;
    case Method::kFramedFullRes:
      schedule.period = double(s.width) * double(s.height) / s.rate;
      // Its frames do not keep step with the display: where the frames start relative to the
      // animation is the seed's.
      schedule.origin += schedule_phase(s.seed) * schedule.period;
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
    const double t_in = schedule.input_time(k);
    if (k != shown_k) {
      auto start = Steady::now();
      frame = trace_frame(tracer, t_in, w, h, threads, &ts);
      stats.sample_seconds += seconds_since(start);
      ++stats.frames_traced;
      start = Steady::now();
      shown = (w == s.width && h == s.height) ? frame : upsample_bilinear(frame, s.width, s.height);
      stats.reconstruct_seconds += seconds_since(start);
      shown_k = k;
    }
    sink(j, shown, FrameInput{t_in, t_in});
  }
  stats.primary_rays = ts.primary_rays;
  stats.shadow_rays = ts.shadow_rays;
  stats.charged_rays = double(ts.primary_rays);
  stats.virtual_seconds = double(stats.frames_traced) * schedule.period;
  return stats;
}

// Framed 60 Hz with temporal accumulation (taa.h), double buffered like framed 60 Hz: the
// frame shown at t_j is frame j - 1, traced with the input of t_(j-1) (or older, with a
// latency above one refresh).
RunStats run_taa(const Scene& scene, Tracer& tracer, const RunSettings& s, const FrameSink& sink) {
  RunStats stats;
  int w, h;
  framed_resolution(s.rate / s.fps, s.width, s.height, &w, &h);
  stats.frame_width = w;
  stats.frame_height = h;
  stats.frame_period = 1.0 / s.fps;
  FrameSchedule schedule{s.first_time, 1.0 / s.fps, s.latency};
  TemporalAccumulator taa(s.width, s.height, w, h, s.taa);
  const int threads = thread_count(s.threads);
  TraceStats ts;
  // The seed moves where in the 16-frame jitter sequence the run starts.
  const int64_t jitter_offset = int64_t((s.seed - 1) % 16) * 7;
  const int64_t first_k =
      schedule.frame_shown_at(frame_time(s, 0)) - int64_t(std::ceil(s.warmup * s.fps));
  const Image* shown = nullptr;
  int64_t k = first_k;
  for (int j = 0; j < s.frames; ++j) {
    const int64_t want = schedule.frame_shown_at(frame_time(s, j));
    for (; k <= want; ++k) {
      shown = &taa.render(tracer, k + jitter_offset, schedule.input_time(k), threads, &ts);
      ++stats.frames_traced;
    }
    const double t_in = schedule.input_time(want);
    sink(j, *shown, FrameInput{t_in, t_in});
  }
  stats.primary_rays = ts.primary_rays;
  stats.shadow_rays = ts.shadow_rays;
  stats.charged_rays = double(ts.primary_rays);
  stats.virtual_seconds = double(stats.frames_traced) * schedule.period;
  stats.sample_seconds = taa.trace_seconds();
  stats.reconstruct_seconds = taa.resolve_seconds();
  return stats;
}

}  // namespace

double schedule_phase(uint64_t seed) {
  const double golden = 0.6180339887498949;
  const double x = double((seed - 1) % 1000003) * golden;
  return x - std::floor(x);
}

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
