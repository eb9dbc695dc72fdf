#include <afr/eval/evaluation.h>

#include <afr/common/camera_path.h>
#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>
#include <afr/eval/ideal_cache.h>
#include <afr/eval/scene_setup.h>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <thread>

namespace afr::eval {

Scene load_animation_scene(const AnimationSpec& spec) {
  Scene scene = load_scene(spec.scene);
  if (!spec.camera_path.empty()) apply_camera_path(read_camera_path(spec.camera_path), &scene);
  return scene;
}

namespace {

// A window past the end of the animation shows its last pose: legal, but rarely meant.
void warn_about_window(const AnimationSpec& spec, const Scene& scene, double seconds) {
  if (!scene.is_animated()) {
    spdlog::warn("{}: the scene does not move (no animation channels)", spec.name);
  } else if (spec.start + seconds > scene.duration() + 1e-9) {
    spdlog::warn("{}: frames after {:.3f} s show the animation's last pose (its keys end there)",
                 spec.name, scene.duration());
  }
}

}  // namespace

std::vector<Image> ideal_frames(const Scene& scene, Tracer& tracer, const EvalConfig& config,
                                double first_time, int frames, Progress* progress,
                                AnimationResult* result) {
  const int strata = int(std::lround(std::sqrt(double(config.ideal_spp))));
  if (strata < 1 || strata * strata != config.ideal_spp) {
    throw Error(fmt::format("ideal spp {} is not a square (1, 4, 9, 16, ...)", config.ideal_spp));
  }
  std::optional<IdealCache> cache;
  if (!config.cache.empty()) cache.emplace(config.cache, render_fingerprint(scene));
  IdealRenderOptions o;
  o.width = config.base.width;
  o.height = config.base.height;
  o.strata = strata;
  o.threads = config.base.threads;
  std::vector<Image> out;
  out.reserve(size_t(frames));
  double seconds = 0.0;
  uint64_t rendered = 0;
  for (int j = 0; j < frames; ++j) {
    o.time = first_time + double(j) / config.base.fps;
    if (cache) {
      out.push_back(cache->frame(tracer, o));
    } else {
      IdealRenderStats stats;
      out.push_back(render_ideal(tracer, o, &stats));
      seconds += stats.seconds;
      ++rendered;
    }
    if (progress) progress->advance();
  }
  if (result) {
    result->ideal_seconds = cache ? cache->stats().render_seconds : seconds;
    result->ideal_rendered = cache ? cache->stats().misses : rendered;
    result->ideal_cached = cache ? cache->stats().hits : 0;
  }
  return out;
}

namespace {

// The ideal frames as the display codes their comparisons read: converted once per animation,
// not once per run.
std::vector<Srgb8Image> display_codes(const std::vector<Image>& frames) {
  std::vector<Srgb8Image> out;
  out.reserve(frames.size());
  for (const Image& f : frames) out.push_back(to_srgb8(f));
  return out;
}

RunResult compare_run(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                      const std::vector<Srgb8Image>& ideal, const std::vector<int>& strip_frames,
                      Progress* progress) {
  AFR_CHECK(ideal.size() == size_t(settings.frames));
  RunResult r;
  r.method = settings.method;
  r.rate = method_uses_rate(settings.method)
               ? settings.rate
               : double(settings.width) * settings.height * settings.fps;
  r.seed = settings.seed;
  r.rms.resize(size_t(settings.frames));
  r.frame_times.resize(size_t(settings.frames));
  r.inputs.resize(size_t(settings.frames));
  r.stats =
      run_method(scene, tracer, settings, [&](int j, const Image& image, const FrameInput& in) {
        r.rms[size_t(j)] = rms_error_255(image, ideal[size_t(j)]);
        r.frame_times[size_t(j)] = frame_time(settings, j);
        r.inputs[size_t(j)] = in;
        for (int f : strip_frames) {
          if (f == j) r.strip_images[j] = image;
        }
        if (progress) progress->advance();
      });
  r.mean_rms = std::accumulate(r.rms.begin(), r.rms.end(), 0.0) / double(r.rms.size());
  return r;
}

}  // namespace

RunResult run_and_compare(const Scene& scene, Tracer& tracer, const RunSettings& settings,
                          const std::vector<Image>& ideal, const std::vector<int>& strip_frames,
                          Progress* progress) {
  return compare_run(scene, tracer, settings, display_codes(ideal), strip_frames, progress);
}

JobSplit job_split(const EvalConfig& config) {
  const int cores = config.base.threads > 0 ? config.base.threads
                                            : std::max(1, int(std::thread::hardware_concurrency()));
  JobSplit split;
  split.jobs = config.jobs > 0 ? config.jobs : cores;
  split.threads_per_run = std::max(1, cores / split.jobs);
  return split;
}

TracerOptions tracer_options(const JobSplit& split) {
  TracerOptions options;
  options.embree_threads = split.threads_per_run;
  return options;
}

std::vector<RunResult> run_all(const Scene& scene, Tracer& tracer,
                               const std::vector<RunSettings>& runs,
                               const std::vector<Image>& ideal, int jobs,
                               const std::string& animation, const std::vector<int>& strips,
                               uint64_t strip_seed, Progress* progress) {
  // Started costliest first (cost ~ rays per second), so that the last ones to end are short.
  std::vector<size_t> order(runs.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return runs[a].rate > runs[b].rate; });
  const std::vector<Srgb8Image> ideal_codes = display_codes(ideal);
  std::vector<RunResult> done(runs.size());
  std::atomic<size_t> next{0}, finished{0};
  std::mutex error_mutex;
  std::exception_ptr error;
  const std::vector<int> none;
  const auto work = [&](Tracer* own) {
    for (size_t k = next++; k < order.size(); k = next++) {
      const RunSettings& s = runs[order[k]];
      try {
        RunResult r = compare_run(scene, *own, s, ideal_codes, s.seed == strip_seed ? strips : none,
                                  progress);
        r.animation = animation;
        spdlog::debug(
            "{} {} {:.0f} seed {}: mean RMS {:.2f}, {:.1f} s sampling, {:.1f} s reconstruction",
            animation, method_name(s.method), r.rate, s.seed, r.mean_rms, r.stats.sample_seconds,
            r.stats.reconstruct_seconds);
        done[order[k]] = std::move(r);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = order.size();
      }
      if (progress) {
        progress->set_task(
            fmt::format("{}: {} of {} runs done", animation, ++finished, runs.size()));
      }
    }
  };
  if (progress) {
    progress->set_task(fmt::format("{}: {} runs, {} at a time", animation, runs.size(), jobs));
  }
  // A tracer per worker: a tracer holds the scene at one time (Tracer::set_time). They share
  // the first's build of the scene.
  std::vector<std::unique_ptr<Tracer>> tracers;
  for (int w = 1; w < std::min<int>(jobs, int(runs.size())); ++w) {
    tracers.push_back(std::make_unique<Tracer>(tracer, Tracer::ShareGeometry{}));
  }
  std::vector<std::thread> workers;
  for (auto& t : tracers) workers.emplace_back(work, t.get());
  work(&tracer);
  for (std::thread& w : workers) w.join();
  if (error) std::rethrow_exception(error);
  return done;
}

std::vector<AnimationResult> evaluate(const EvalConfig& config) {
  const std::vector<Method> methods =
      config.methods.empty() ? std::vector<Method>(all_methods().begin(), all_methods().end())
                             : config.methods;
  const int frames = std::max(1, int(std::lround(config.seconds * config.base.fps)));
  std::vector<int> strips;
  for (int f : config.strip_frames) strips.push_back(std::clamp(f, 0, frames - 1));

  const int seeds = std::max(1, config.seeds);
  // Units: ideal frames, then every compared frame of every run.
  uint64_t runs_per_animation = 0;
  for (Method m : methods) {
    runs_per_animation +=
        (method_uses_rate(m) ? config.rates.size() : 1) * (method_uses_seed(m) ? seeds : 1);
  }
  Progress progress(config.animations.size() * uint64_t(frames) * (1 + runs_per_animation),
                    config.progress);

  const JobSplit split = job_split(config);
  const int jobs = split.jobs;
  std::vector<AnimationResult> results;
  for (const AnimationSpec& spec : config.animations) {
    AnimationResult ar;
    ar.spec = spec;
    progress.set_task(fmt::format("{}: loading", spec.name));
    const Scene scene = load_animation_scene(spec);
    warn_about_window(spec, scene, config.seconds);
    Tracer tracer(scene, tracer_options(split));
    progress.set_task(fmt::format("{}: ideal frames ({} spp)", spec.name, config.ideal_spp));
    const std::vector<Image> ideal =
        ideal_frames(scene, tracer, config, spec.start, frames, &progress, &ar);
    for (int j = 0; j < frames; ++j) ar.frame_times.push_back(spec.start + j / config.base.fps);
    ar.duration = scene.is_animated() ? scene.duration() : 0.0;
    ar.still_frames = int(std::count_if(ar.frame_times.begin(), ar.frame_times.end(),
                                        [&](double t) { return t > ar.duration + 1e-9; }));
    for (int f : strips) ar.ideal_strip_images[f] = ideal[size_t(f)];
    // Every (method, rate, seed) run of the animation, in table order.
    std::vector<RunSettings> runs;
    for (Method m : methods) {
      const std::vector<double> rates =
          method_uses_rate(m) ? config.rates : std::vector<double>{0.0};
      for (double rate : rates) {
        for (int k = 0; k < (method_uses_seed(m) ? seeds : 1); ++k) {
          RunSettings s = config.base;
          s.method = m;
          s.rate = method_uses_rate(m) ? rate : double(s.width) * s.height * s.fps;
          s.seed = config.base.seed + uint64_t(k);
          s.first_time = spec.start;
          s.frames = frames;
          s.threads = split.threads_per_run;
          runs.push_back(s);
        }
      }
    }
    std::vector<RunResult> done =
        run_all(scene, tracer, runs, ideal, jobs, spec.name, strips, config.base.seed, &progress);
    for (RunResult& r : done) ar.runs.push_back(std::move(r));
    results.push_back(std::move(ar));
  }
  progress.finish();
  return results;
}

void render_ideal_only(const EvalConfig& config) {
  const int frames = std::max(1, int(std::lround(config.seconds * config.base.fps)));
  Progress progress(config.animations.size() * uint64_t(frames), config.progress);
  for (const AnimationSpec& spec : config.animations) {
    progress.set_task(fmt::format("{}: loading", spec.name));
    const Scene scene = load_animation_scene(spec);
    warn_about_window(spec, scene, config.seconds);
    Tracer tracer(scene);
    progress.set_task(fmt::format("{}: ideal frames ({} spp)", spec.name, config.ideal_spp));
    AnimationResult ar;
    ideal_frames(scene, tracer, config, spec.start, frames, &progress, &ar);
    spdlog::info("{}: {} ideal frames rendered ({:.0f} s), {} from the cache", spec.name,
                 ar.ideal_rendered, ar.ideal_seconds, ar.ideal_cached);
  }
  progress.finish();
}

}  // namespace afr::eval
