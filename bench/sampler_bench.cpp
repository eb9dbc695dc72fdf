// afr-bench-sampler: what the sampler's control costs, measured side by side in one run.
//   afr-bench-sampler [--scene kitchen.gltf] [--seconds 1.5] [--repeats 5]
// Prints a Markdown table per scene. Single-thread figures are per CPU-second of the thread, so
// that other work on the machine does not enter them:
//  - control overhead: adaptive samples/s over uniform-random samples/s (same tracer,
//    shading, sink, thread); the paper reports the control costs under 15%;
//  - reprojection bookkeeping (without its occlusion ray) over the cost of a new crosshair,
//    and the occlusion ray's cost apart (the paper: a reprojection costs ~1/35 of a sample);
//  - samples/s of the threaded pool with 1 and 2 threads.
// With --profile MODE it instead runs a fixed number of steps of one mode in profile_steps(),
// for counting instructions reproducibly: adaptive, uniform, crosshair (adaptive steps with
// r = 0: a new crosshair each) or reproject (reprojections alone, without occlusion rays):
//   valgrind --tool=callgrind --toggle-collect='*profile_steps*' afr-bench-sampler --profile
//   adaptive
#include <afr/common/builtin_scene.h>
#include <afr/common/cli.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>
#include <afr/common/random.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/sampler_pool.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <ctime>
#include <thread>
#include <vector>

namespace {

struct CountingSink final : afr::SampleSink {
  std::atomic<uint64_t> samples{0};
  void on_batch(afr::SampleBatch&& b) override { samples += b.samples.size(); }
  void on_tiling(afr::TilingSnapshot&&) override {}
};

// Counts samples and digests them (FNV-1a over the bits of position, time and color, a word at
// a time), so that a change that should not alter the sample stream can be checked to leave it
// bit for bit the same.
uint64_t fnv(uint64_t h, const double* v, size_t n) {
  for (size_t k = 0; k < n; ++k) h = (h ^ std::bit_cast<uint64_t>(v[k])) * 1099511628211ULL;
  return h;
}

struct DigestSink final : afr::SampleSink {
  uint64_t samples = 0;
  uint64_t digest = 1469598103934665603ULL;
  void on_batch(afr::SampleBatch&& b) override {
    for (const afr::Sample& s : b.samples) {
      const double v[6] = {s.time, s.x, s.y, s.color.r, s.color.g, s.color.b};
      digest = fnv(digest, v, 6);
    }
    samples += b.samples.size();
  }
  void on_tiling(afr::TilingSnapshot&&) override {}
};

// CPU seconds of the calling thread: on a machine shared with other work, time spent waiting for
// a core does not count against either variant.
double thread_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Run {
  double seconds_per_step = 0.0;
  double samples_per_second = 0.0;
  afr::SamplerCounters counters;
};

// Runs one sampler on one thread for `seconds` of the thread's CPU time (under a virtual clock
// at 400K rays/s, so the scene animates as it would live) and reports its throughput per
// CPU-second.
Run run_single(const afr::Scene& scene, afr::Tracer& tracer, afr::SamplerConfig config,
               double seconds) {
  afr::VirtualClock clock(4e5, 1.0);
  CountingSink sink;
  afr::Sampler sampler(scene, tracer, clock, config, sink);
  sampler.fill();
  const uint64_t start_samples = sampler.counters().samples;
  const double start = thread_seconds();
  uint64_t steps = 0;
  double elapsed = 0.0;
  while (elapsed < seconds) {
    for (int k = 0; k < 256; ++k) sampler.step();
    steps += 256;
    elapsed = thread_seconds() - start;
  }
  Run r;
  r.seconds_per_step = elapsed / double(steps);
  r.samples_per_second = double(sampler.counters().samples - start_samples) / elapsed;
  r.counters = sampler.counters();
  return r;
}

double run_pool(const afr::Scene& scene, const afr::SamplerConfig& config, int threads,
                double seconds) {
  afr::WallClock clock;
  CountingSink sink;
  afr::SamplerPoolOptions options;
  options.threads = threads;
  afr::SamplerPool pool(scene, config, options, clock, sink);
  pool.start();
  std::this_thread::sleep_for(std::chrono::duration<double>(0.2));  // past the initial fill
  const uint64_t s0 = sink.samples;
  const auto t0 = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const uint64_t s1 = sink.samples;
  const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  pool.stop();
  return double(s1 - s0) / dt;
}

// Times `calls` invocations of f, returns seconds per call.
template <typename F>
double time_per_call(int calls, F&& f) {
  const double start = thread_seconds();
  for (int k = 0; k < calls; ++k) f(k);
  return (thread_seconds() - start) / calls;
}

// The cost of one reprojection, without its occlusion ray, and of one occlusion ray, against one
// step without reprojection (one new crosshair, the next crosshair's first sample, a share of
// the tiling adjustment), on a sampler that has run for a while at a moving time.
void reprojection_costs(const afr::Scene& scene, afr::Tracer& tracer, afr::SamplerConfig config,
                        double* bookkeeping_ratio, double* occlusion_ratio) {
  config.r = 0;
  afr::VirtualClock clock(4e5, 2.0);
  CountingSink sink;
  afr::Sampler s0(scene, tracer, clock, config, sink);
  s0.fill();
  for (int k = 0; k < 20000; ++k) s0.step();
  const int calls = 20000;
  const double step = time_per_call(calls, [&](int) { s0.step(); });
  config.occlusion_rays = false;
  afr::Sampler s1(scene, tracer, clock, config, sink);
  s1.fill();
  for (int k = 0; k < 20000; ++k) s1.step();
  afr::Pcg32 rng(5);
  // Per reprojection done: a call that picks an empty pixel does none, and its (small) cost is
  // charged to the calls that do.
  const auto& tiles = s1.tiling().tiles();
  const uint64_t done1 = s1.counters().reprojections;
  const double plain =
      time_per_call(calls,
                    [&](int) { s1.reproject(tiles[rng.next_below(uint32_t(tiles.size()))]); }) *
      calls / std::max<double>(1.0, double(s1.counters().reprojections - done1));
  config.occlusion_rays = true;
  afr::Sampler s2(scene, tracer, clock, config, sink);
  s2.fill();
  for (int k = 0; k < 20000; ++k) s2.step();
  const auto& tiles2 = s2.tiling().tiles();
  const afr::SamplerCounters c0 = s2.counters();
  const double with_ray =
      time_per_call(calls,
                    [&](int) { s2.reproject(tiles2[rng.next_below(uint32_t(tiles2.size()))]); }) *
      calls;
  const afr::SamplerCounters& c1 = s2.counters();
  const double rays = double(c1.occlusion_rays - c0.occlusion_rays);
  // Occluded crosshairs are replaced by newly traced ones; that tracing is sampling, not
  // occlusion testing, so it is taken out at the cost of a step per 5 samples.
  const double replaced = double(c1.samples - c0.samples) / 5.0;
  const double done2 = double(c1.reprojections - c0.reprojections);
  *bookkeeping_ratio = plain / step;
  *occlusion_ratio =
      std::max(0.0, with_ray - done2 * plain - replaced * step) / std::max(rays, 1.0) / step;
}

void bench_scene(const afr::Scene& scene, const std::string& name, int size, double seconds,
                 int repeats) {
  afr::Tracer tracer(scene);
  afr::SamplerConfig base;
  base.image.width = base.image.height = size;
  std::vector<double> adaptive, uniform, ratio, repro_ratio, occl_ratio;
  for (int rep = 0; rep < repeats; ++rep) {
    afr::SamplerConfig u = base;
    u.mode = afr::SamplerMode::kUniformRandom;
    // Interleaved, so machine noise hits every variant alike.
    const Run ra = run_single(scene, tracer, base, seconds);
    const Run ru = run_single(scene, tracer, u, seconds);
    adaptive.push_back(ra.samples_per_second);
    uniform.push_back(ru.samples_per_second);
    ratio.push_back(ra.samples_per_second / ru.samples_per_second);
    double b, o;
    reprojection_costs(scene, tracer, base, &b, &o);
    repro_ratio.push_back(b);
    occl_ratio.push_back(o);
  }
  const double one = run_pool(scene, base, 1, seconds);
  const double two = run_pool(scene, base, 2, seconds);
  fmt::print("\n### {} ({}x{}, {} triangles), median of {}\n\n", name, size, size,
             scene.triangle_count(), repeats);
  fmt::print("| measure | value |\n|---|---|\n");
  fmt::print("| adaptive samples per CPU-second (1 thread) | {:.0f} |\n", median(adaptive));
  fmt::print("| uniform random samples per CPU-second (1 thread) | {:.0f} |\n", median(uniform));
  fmt::print("| control overhead ratio adaptive/uniform (goal >= 0.90) | {:.3f} |\n",
             median(ratio));
  fmt::print("| reprojection bookkeeping / new crosshair (goal <= 1/50) | 1/{:.1f} |\n",
             1.0 / std::max(1e-9, median(repro_ratio)));
  const double occl = median(occl_ratio);
  fmt::print("| occlusion ray / new crosshair | {} |\n",
             occl > 0.0 ? fmt::format("1/{:.1f}", 1.0 / occl) : "below the noise");
  fmt::print("| pool samples/s, 1 thread (wall clock) | {:.0f} |\n", one);
  fmt::print("| pool samples/s, 2 threads (wall clock) | {:.0f} ({:.2f}x) |\n", two, two / one);
}

// The steps counted under --profile: kept out of line so that callgrind can collect only them.
[[gnu::noinline]] void profile_steps(afr::Sampler& sampler, const std::string& mode, int steps) {
  if (mode == "reproject") {
    afr::Pcg32 rng(5);
    const auto& tiles = sampler.tiling().tiles();
    for (int k = 0; k < steps; ++k)
      sampler.reproject(tiles[rng.next_below(uint32_t(tiles.size()))]);
  } else {
    for (int k = 0; k < steps; ++k) sampler.step();
  }
}

// A fixed, seeded run of one mode under a virtual clock: fill, `steps` steps to settle, then
// `steps` steps (or, for "reproject", reprojections without occlusion rays on a sampler with
// r = 0) in profile_steps(). Prints what the profiled part did and digests of the sample
// stream and of the tiles' statistics.
void profile(const afr::Scene& scene, const std::string& mode, int size, int steps) {
  afr::Tracer tracer(scene);
  afr::SamplerConfig config;
  config.image.width = config.image.height = size;
  if (mode == "uniform") config.mode = afr::SamplerMode::kUniformRandom;
  if (mode == "reproject" || mode == "crosshair") config.r = 0;
  if (mode == "reproject") config.occlusion_rays = false;
  afr::VirtualClock clock(4e5, 2.0);
  DigestSink sink;
  afr::Sampler sampler(scene, tracer, clock, config, sink);
  sampler.fill();
  for (int k = 0; k < steps; ++k) sampler.step();
  const afr::SamplerCounters before = sampler.counters();
  profile_steps(sampler, mode, steps);
  const afr::SamplerCounters& after = sampler.counters();
  sampler.flush();
  // And the state the loop leaves: every tile's rectangle and statistics.
  uint64_t state = 1469598103934665603ULL;
  for (int t : mode == "uniform" ? std::vector<int>{} : sampler.tiling().tiles()) {
    const afr::TileStats st = sampler.tile_stats(t);
    const afr::PixelRect r = sampler.tiling().node(t).rect;
    const double v[10] = {double(r.x0), double(r.y0), double(r.x1), double(r.y1), st.v,
                          st.G_x,       st.G_y,       st.G_t,       st.mean_age,  double(st.count)};
    state = fnv(state, v, 10);
  }
  fmt::print(
      "{} {} steps: {} samples, {} crosshairs, {} reprojections, {} occlusion rays, {} splits; "
      "stream digest {:016x}, state digest {:016x}\n",
      mode, steps, after.samples - before.samples, after.crosshairs - before.crosshairs,
      after.reprojections - before.reprojections, after.occlusion_rays - before.occlusion_rays,
      after.splits - before.splits, sink.digest, state);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-sampler: the cost of adaptive control, side by side"};
  std::string scene_path;
  double seconds = 1.5;
  int repeats = 5, size = 256;
  app.add_option("--scene", scene_path, "also measure this glTF scene")->check(CLI::ExistingFile);
  app.add_option("--seconds", seconds, "wall seconds per measurement")
      ->check(CLI::Range(0.1, 60.0));
  app.add_option("--repeats", repeats, "repeats (median reported)")->check(CLI::Range(1, 101));
  app.add_option("--size", size, "square image size")->check(CLI::Range(16, 4096));
  std::string profile_mode;
  int profile_count = 20000;
  app.add_option("--profile", profile_mode,
                 "run only a fixed number of steps of one mode (for callgrind) on the --scene "
                 "or the built-in scene")
      ->check(CLI::IsMember({"adaptive", "uniform", "reproject", "crosshair"}));
  app.add_option("--steps", profile_count, "steps under --profile")
      ->check(CLI::Range(1, 100000000));
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging("warn");
    if (!profile_mode.empty()) {
      profile(scene_path.empty() ? afr::make_builtin_scene() : afr::load_gltf(scene_path),
              profile_mode, size, profile_count);
      return 0;
    }
    bench_scene(afr::make_builtin_scene(), "built-in scene", size, seconds, repeats);
    if (!scene_path.empty()) {
      bench_scene(afr::load_gltf(scene_path), scene_path, size, seconds, repeats);
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 1;
  }
  return 0;
}
