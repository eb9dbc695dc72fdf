// afr-bench-tracer: throughput of the tracer (shaded samples/s and rays/s) on the built-in
// scene and on a glTF scene, for single rays at random image positions and for crosshairs cast
// as five single rays or as one 8-wide packet, on 1 and 2 threads, at several animation times.
// Prints a Markdown table of medians over repeats.
//   afr-bench-tracer --scene ../shared/scenes/bart-kitchen/kitchen.gltf --times 0,5,10
#include <afr/common/builtin_scene.h>
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>
#include <afr/common/random.h>
#include <afr/sampler/tracer.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

enum class Mode { kRandomRays, kCrosshairSingle, kCrosshairPacket };

const char* mode_name(Mode m) {
  switch (m) {
    case Mode::kRandomRays:
      return "random rays";
    case Mode::kCrosshairSingle:
      return "crosshair, 5 x rtcIntersect1";
    case Mode::kCrosshairPacket:
      return "crosshair, rtcIntersect8";
  }
  return "?";
}

struct RunResult {
  double samples_per_s = 0.0;
  double samples_per_cpu_s = 0.0;  // per second of the tracing threads' CPU time
  double rays_per_s = 0.0;         // primary + shadow + reflection
  double rays_per_sample = 0.0;
  uint64_t sanitized = 0;
};

// CPU time of the calling thread: unlike wall time, it does not count time the thread waited
// for a core that another process held.
double thread_cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Traces `samples` shaded samples split over `threads` threads; each thread draws its image
// positions from its own seeded generator.
RunResult run_once(const afr::Tracer& tracer, Mode mode, int threads, int width, int height,
                   uint64_t samples, uint64_t seed) {
  std::vector<afr::TraceStats> stats(static_cast<size_t>(threads));
  std::vector<double> cpu_seconds(static_cast<size_t>(threads));
  const afr::Camera camera = tracer.camera();
  const uint64_t per_thread = samples / uint64_t(threads);
  auto work = [&](int index) {
    const double cpu_start = thread_cpu_seconds();
    afr::Pcg32 rng(afr::mix_seed(seed), uint64_t(index));
    afr::TraceStats st;  // thread-local: shared cache lines would serialise the threads
    float sink = 0.0f;   // keeps the results alive
    if (mode == Mode::kRandomRays) {
      for (uint64_t i = 0; i < per_thread; ++i) {
        const double x = rng.next_double() * width, y = rng.next_double() * height;
        sink += tracer.trace(camera.ray(x, y, width, height), &st).color.g;
      }
    } else {
      std::array<afr::ShadedSample, 5> cross;
      for (uint64_t i = 0; i < per_thread; i += 5) {
        const double x = rng.next_double() * width, y = rng.next_double() * height;
        tracer.trace_crosshair(camera, x, y, width, height, &cross, &st);
        sink += cross[0].color.g;
      }
    }
    if (sink < 0.0f) fmt::print("");  // never true: colors are >= 0
    stats[size_t(index)] = st;
    cpu_seconds[size_t(index)] = thread_cpu_seconds() - cpu_start;
  };
  const auto start = Clock::now();
  std::vector<std::thread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(work, i);
  work(0);
  for (std::thread& t : pool) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  afr::TraceStats total;
  for (const afr::TraceStats& s : stats) total += s;
  const double rays = double(total.primary_rays + total.shadow_rays + total.reflection_rays);
  RunResult r;
  r.samples_per_s = double(total.primary_rays) / seconds;
  double cpu = 0.0;
  for (double c : cpu_seconds) cpu += c;
  r.samples_per_cpu_s = double(total.primary_rays) / std::max(cpu, 1e-9);
  r.rays_per_s = rays / seconds;
  r.rays_per_sample = rays / double(std::max<uint64_t>(total.primary_rays, 1));
  r.sanitized = total.sanitized;
  return r;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::vector<double> parse_times(const std::string& text) {
  std::vector<double> times;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string part = text.substr(start, comma - start);
    try {
      size_t used = 0;
      times.push_back(std::stod(part, &used));
      if (used != part.size()) throw std::invalid_argument(part);
    } catch (const std::exception&) {
      throw afr::Error(fmt::format("--times '{}': '{}' is not a number", text, part));
    }
    start = comma + 1;
  }
  return times;
}

std::string si(double v) {
  if (v >= 1e6) return fmt::format("{:.2f} M", v * 1e-6);
  if (v >= 1e3) return fmt::format("{:.1f} k", v * 1e-3);
  return fmt::format("{:.0f}", v);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-tracer: tracer throughput (shaded samples/s, rays/s)"};
  std::string scene_path, size_text = "640x480", times_text = "0,2.5,5,7.5", log_level = "warn";
  uint64_t samples = 200000, seed = 1;
  int repeats = 5, max_threads = 2;
  bool skip_builtin = false;
  app.add_option("--scene", scene_path, "a glTF scene (e.g. the converted BART kitchen)")
      ->check(CLI::ExistingFile);
  app.add_flag("--no-builtin", skip_builtin, "skip the built-in scene");
  app.add_option("-s,--size", size_text, "image size WxH")->capture_default_str();
  app.add_option("--times", times_text, "animation times in seconds, comma-separated")
      ->capture_default_str();
  app.add_option("--samples", samples, "shaded samples per run")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(10), uint64_t(1) << 40));
  app.add_option("--repeats", repeats, "runs per figure (the median is shown)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_option("-j,--threads", max_threads, "thread counts 1..N are measured")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  app.add_option("--seed", seed, "seed of the image positions");
  app.add_option("--log", log_level, "log level")->capture_default_str();
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    const afr::ImageExtent size = afr::parse_image_size(size_text);
    const std::vector<double> times = parse_times(times_text);

    std::vector<afr::Scene> scenes;
    if (!skip_builtin) scenes.push_back(afr::make_builtin_scene());
    if (!scene_path.empty()) scenes.push_back(afr::load_gltf(scene_path));
    std::vector<std::string> names;
    for (const afr::Scene& s : scenes)
      names.push_back(std::filesystem::path(s.source).filename().string());

    fmt::print(
        "## afr-bench-tracer\n\n{}x{} image, {} samples per run, median of {} runs, "
        "{} hardware threads\n\n",
        size.width, size.height, samples, repeats, std::thread::hardware_concurrency());
    fmt::print("| scene | triangles | build (ms) | set_time (ms) |\n|---|---:|---:|---:|\n");
    std::vector<std::array<std::unique_ptr<afr::Tracer>, 2>> tracers;
    for (const afr::Scene& scene : scenes) {
      afr::TracerOptions single, packet;
      single.packet_crosshair = false;
      packet.packet_crosshair = true;
      const auto t0 = Clock::now();
      auto a = std::make_unique<afr::Tracer>(scene, single);
      const double build_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      auto b = std::make_unique<afr::Tracer>(scene, packet);
      const int kSetTimes = 100;
      const auto t1 = Clock::now();
      for (int i = 0; i < kSetTimes; ++i) a->set_time(0.01 * i);
      const double set_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - t1).count() / kSetTimes;
      fmt::print("| {} | {} | {:.1f} | {:.3f} |\n", scene.source, scene.triangle_count(), build_ms,
                 set_ms);
      tracers.push_back({std::move(a), std::move(b)});
    }

    const std::vector<Mode> modes = {Mode::kRandomRays, Mode::kCrosshairSingle,
                                     Mode::kCrosshairPacket};
    for (size_t sc = 0; sc < scenes.size(); ++sc) {
      fmt::print(
          "\n| scene | t (s) | mode | threads | samples/s | samples/CPU-s | rays/s | "
          "rays/sample |\n|---|---:|---|---:|---:|---:|---:|---:|\n");
      // Medians per configuration, summed over times: the summary below.
      std::vector<double> wall_sum(modes.size() * size_t(max_threads), 0.0);
      std::vector<double> cpu_sum(wall_sum.size(), 0.0);
      uint64_t sanitized = 0;  // NaN or Inf values the tracer replaced: should stay 0
      for (double t : times) {
        for (auto& tr : tracers[sc]) tr->set_time(t);
        // Every repeat runs every configuration once, so that load from other processes
        // spreads over all of them alike.
        const size_t configs = modes.size() * size_t(max_threads);
        std::vector<std::vector<RunResult>> results(configs);
        for (int r = 0; r < repeats; ++r) {
          for (size_t c = 0; c < configs; ++c) {
            const Mode mode = modes[c / size_t(max_threads)];
            const int threads = int(c % size_t(max_threads)) + 1;
            const afr::Tracer& tracer = *tracers[sc][mode == Mode::kCrosshairPacket ? 1 : 0];
            results[c].push_back(run_once(tracer, mode, threads, size.width, size.height, samples,
                                          seed + uint64_t(r)));
          }
        }
        for (size_t c = 0; c < configs; ++c) {
          const Mode mode = modes[c / size_t(max_threads)];
          const int threads = int(c % size_t(max_threads)) + 1;
          auto med = [&](double RunResult::*field) {
            std::vector<double> v;
            for (const RunResult& res : results[c]) v.push_back(res.*field);
            return median(v);
          };
          for (const RunResult& res : results[c]) sanitized += res.sanitized;
          const double per_cpu = med(&RunResult::samples_per_cpu_s);
          const double per_s = med(&RunResult::samples_per_s);
          wall_sum[c] += per_s;
          cpu_sum[c] += per_cpu;
          fmt::print("| {} | {:g} | {} | {} | {} | {} | {} | {:.2f} |\n", names[sc], t,
                     mode_name(mode), threads, si(per_s), si(per_cpu),
                     si(med(&RunResult::rays_per_s)), med(&RunResult::rays_per_sample));
        }
        std::fflush(stdout);
      }
      // Summary: mean over times, and the packet vs single-ray crosshair ratio (per CPU-second,
      // which other processes on the machine disturb less than wall time).
      fmt::print(
          "\n**{}**, mean over t = {}: samples/s (samples/CPU-s); {} sanitized values\n\n"
          "| threads | random rays | crosshair, 5 x rtcIntersect1 | crosshair, rtcIntersect8 | "
          "packet / single |\n|---:|---:|---:|---:|---:|\n",
          names[sc], times_text, sanitized);
      const double n = double(times.size());
      for (int threads = 1; threads <= max_threads; ++threads) {
        auto cell = [&](size_t m) {
          const size_t c = m * size_t(max_threads) + size_t(threads - 1);
          return fmt::format("{} ({})", si(wall_sum[c] / n), si(cpu_sum[c] / n));
        };
        const size_t single_c = 1 * size_t(max_threads) + size_t(threads - 1);
        const size_t packet_c = 2 * size_t(max_threads) + size_t(threads - 1);
        fmt::print("| {} | {} | {} | {} | {:.3f} |\n", threads, cell(0), cell(1), cell(2),
                   cpu_sum[packet_c] / std::max(cpu_sum[single_c], 1e-9));
      }
    }
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
