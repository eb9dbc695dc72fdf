// afr-bench-reconstruct: time of one reconstruct() call (display refresh) versus resolution,
// with N = 4 x pixels samples in the store, for the CPU backend on 1 and 2 threads and the
// OpenGL backend (whatever driver EGL gives: llvmpipe here). Like a live display, every timed
// refresh first receives 1/60 s worth of new samples (the store turning over once a second)
// and a new tiling, and reprojects everything for a slightly moved camera. Prints a Markdown
// table of medians over repeats, wall time and process CPU time, with a naive 3 x 3 splat as
// a yardstick of the machine's speed.
//   afr-bench-reconstruct --sizes 256,512,1024 --repeats 15
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/common/random.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/display/gl_context.h>
#include <afr/display/gl_reconstructor.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace {

// A floor under a sky, sampled with world positions (so the reconstructor reprojects), and
// colors that vary at several scales.
afr::Sample make_sample(const afr::Camera& camera, afr::Pcg32& rng, int size, double time) {
  afr::Sample s;
  s.x = rng.next_float() * float(size);
  s.y = rng.next_float() * float(size);
  s.time = time;
  const afr::Ray ray = camera.ray(s.x, s.y, size, size);
  if (ray.direction.y < -1e-6f) {
    const float t = (-1.0f - ray.origin.y) / ray.direction.y;
    s.position = ray.origin + t * ray.direction;
    const float checker = (int(std::floor(s.position.x)) + int(std::floor(s.position.z))) & 1;
    s.color = glm::vec3(0.2f + 0.6f * checker, 0.4f, 0.3f + 0.2f * std::sin(s.position.z));
  } else {
    s.position = ray.direction;
    s.miss = true;
    s.color = glm::vec3(0.3f, 0.5f, 0.9f) * (0.5f + 0.5f * ray.direction.y);
  }
  return s;
}

afr::SampleBatch make_batch(const afr::Camera& camera, afr::Pcg32& rng, int size, size_t n,
                            double t0, double t1) {
  afr::SampleBatch b;
  b.fields = afr::kFieldPosition;
  b.samples.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    b.samples.push_back(make_sample(camera, rng, size, t0 + (t1 - t0) * double(i) / double(n)));
  }
  return b;
}

// 16 x 16 pixel tiles with gradients like the sampler's: mostly static, some edges and motion.
afr::TilingSnapshot make_tiling(afr::Pcg32& rng, int size, double time, double rate) {
  afr::TilingSnapshot s;
  s.time = time;
  s.region = afr::PixelRect{0, 0, size, size};
  for (int y = 0; y < size; y += 16) {
    for (int x = 0; x < size; x += 16) {
      afr::TileInfo t;
      t.rect = afr::PixelRect{x, y, std::min(x + 16, size), std::min(y + 16, size)};
      t.G_x = 0.1f * rng.next_float();
      t.G_y = 0.1f * rng.next_float();
      t.G_t = rng.next_float() < 0.2f ? 2.0f * rng.next_float() : 0.01f * rng.next_float();
      t.rate = float(rate) * (0.5f + rng.next_float());
      s.tiles.push_back(t);
    }
  }
  return s;
}

struct Timing {
  double median = 0.0, p10 = 0.0, p90 = 0.0;
  double cpu = 0.0;  // median CPU time of the whole process (all its threads) per refresh
};

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Timing summarize(std::vector<double> ms, const std::vector<double>& cpu_ms) {
  std::sort(ms.begin(), ms.end());
  const auto at = [&](double q) { return ms[size_t(std::lround(q * double(ms.size() - 1)))]; };
  Timing t;
  t.median = median_of(ms);
  t.p10 = at(0.1);
  t.p90 = at(0.9);
  t.cpu = median_of(cpu_ms);
  return t;
}

// CPU time of this process, all threads (the reconstructor's workers, a GL driver's threads):
// unlike wall time it does not grow while the process waits for a core another process holds.
double process_cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

// The yardstick of the issue: a naive single-threaded splat of every sample into its 3 x 3
// pixels with std::exp weights, no filter adaptation, reprojection or coverage.
Timing naive_splat(int size, int repeats) {
  afr::Pcg32 rng(5);
  const size_t n = 4 * size_t(size) * size_t(size);
  std::vector<glm::vec2> xy(n);
  std::vector<glm::vec3> color(n);
  for (size_t i = 0; i < n; ++i) {
    xy[i] = glm::vec2(rng.next_float(), rng.next_float()) * float(size);
    color[i] = glm::vec3(rng.next_float(), rng.next_float(), rng.next_float());
  }
  std::vector<glm::vec4> acc(size_t(size) * size_t(size));
  std::vector<double> ms, cpu;
  for (int r = 0; r < repeats; ++r) {
    const double c0 = process_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    std::fill(acc.begin(), acc.end(), glm::vec4(0.0f));
    for (size_t i = 0; i < n; ++i) {
      const int cx = int(xy[i].x), cy = int(xy[i].y);
      for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, size - 1); ++y) {
        for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, size - 1); ++x) {
          const glm::vec2 d = glm::vec2(float(x) + 0.5f, float(y) + 0.5f) - xy[i];
          const float w = std::exp(-2.0f * glm::dot(d, d));
          acc[size_t(y) * size_t(size) + size_t(x)] += glm::vec4(color[i] * w, w);
        }
      }
    }
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    cpu.push_back(process_cpu_ms() - c0);
  }
  if (acc[0].w < 0.0f) fmt::print("");  // keeps the sums alive
  return summarize(ms, cpu);
}

// Fills the store, then times `repeats` refreshes after `warmup` untimed ones.
Timing run(afr::Reconstructor& rec, int size, int repeats, int warmup, bool readback,
           uint64_t seed) {
  afr::Pcg32 rng(afr::mix_seed(seed));
  const size_t n = rec.capacity();
  const double rate = double(n) / (double(size) * double(size));  // per pixel per second
  const afr::Camera start =
      afr::Camera::look_at({0.0, 0.5, 0.0}, {0.0, 0.0, -5.0}, {0, 1, 0}, 1.0, 0.01);
  rec.add_batch(make_batch(start, rng, size, n, 0.0, 1.0));  // one second of samples
  double t = 1.0;
  const size_t per_frame = n / 60;
  std::vector<double> ms, cpu;
  afr::Image image;
  for (int frame = 0; frame < warmup + repeats; ++frame) {
    const afr::Camera cam = afr::Camera::look_at({0.01 * frame, 0.5, -0.01 * frame},
                                                 {0.0, 0.0, -5.0}, {0, 1, 0}, 1.0, 0.01);
    rec.add_batch(make_batch(cam, rng, size, per_frame, t, t + 1.0 / 60.0));
    t += 1.0 / 60.0;
    rec.set_tiling(make_tiling(rng, size, t, rate));
    const double c0 = process_cpu_ms();
    rec.reconstruct(cam, t, size, size, readback ? &image : nullptr);
    if (frame >= warmup) {
      ms.push_back(rec.frame_stats().milliseconds);
      cpu.push_back(process_cpu_ms() - c0);
    }
  }
  return summarize(ms, cpu);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-reconstruct: reconstruction time vs resolution, CPU and OpenGL"};
  std::vector<int> sizes{256, 512, 1024}, thread_counts{1, 2};
  std::string backends = "cpu,gl";
  std::string mode_text = "adaptive", log_level = "warn";
  int repeats = 15, warmup = 3, gl_repeats = 7;
  bool readback = true, naive = true;
  app.add_option("--sizes", sizes, "square output sides, comma separated")->delimiter(',');
  app.add_option("--threads", thread_counts, "CPU backend thread counts, comma separated")
      ->delimiter(',');
  app.add_option("--backends", backends, "cpu, gl or cpu,gl");
  app.add_option("--mode", mode_text, "adaptive, adaptive-no-reprojection or frameless");
  app.add_option("--repeats", repeats, "timed refreshes per CPU row");
  app.add_option("--gl-repeats", gl_repeats, "timed refreshes per GL row");
  app.add_option("--warmup", warmup, "untimed refreshes first");
  app.add_option("--readback", readback, "read the image back to memory (GL) / fill it (CPU)");
  app.add_option("--naive", naive, "also time the naive 3x3 splat yardstick");
  app.add_option("--log", log_level, "log level");
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging(log_level);
    const afr::ReconstructionMode mode = afr::parse_mode(mode_text);
    std::string gl_error;
    std::shared_ptr<afr::GlContext> gl;
    if (backends.find("gl") != std::string::npos) {
      gl = afr::EglContext::create_headless(&gl_error);
      if (!gl) fmt::print(stderr, "OpenGL backend skipped: {}\n", gl_error);
    }
    fmt::print(
        "Reconstruction, mode {}, N = 4 x pixels, 1/60 of N new samples per refresh, "
        "median of {} (CPU) / {} (GL) refreshes\n\n",
        afr::mode_name(mode), repeats, gl_repeats);
    fmt::print(
        "| backend | threads | resolution | N | median ms | p10 ms | p90 ms | refreshes/s | "
        "CPU ms |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|\n");
    for (int size : sizes) {
      afr::ReconstructorConfig cfg;
      cfg.image.width = size;
      cfg.image.height = size;
      cfg.mode = mode;
      const size_t n = 4 * size_t(size) * size_t(size);
      const auto row = [&](const std::string& backend, const std::string& threads, Timing t) {
        fmt::print("| {} | {} | {}x{} | {} | {:.2f} | {:.2f} | {:.2f} | {:.0f} | {:.2f} |\n",
                   backend, threads, size, size, n, t.median, t.p10, t.p90, 1000.0 / t.median,
                   t.cpu);
        std::fflush(stdout);
      };
      if (naive) row("naive 3x3 splat (yardstick)", "1", naive_splat(size, repeats));
      if (backends.find("cpu") != std::string::npos) {
        for (int threads : thread_counts) {
          cfg.threads = threads;
          afr::CpuReconstructor rec(cfg);
          row("cpu", std::to_string(threads), run(rec, size, repeats, warmup, readback, 1));
        }
      }
      if (gl) {
        afr::GlReconstructor rec(cfg, gl);
        row("gl (" + gl->renderer() + ")", "-", run(rec, size, gl_repeats, warmup, readback, 1));
      }
    }
  } catch (const afr::Error& e) {
    fmt::print(stderr, "afr-bench-reconstruct: {}\n", e.what());
    return 1;
  }
  return 0;
}
