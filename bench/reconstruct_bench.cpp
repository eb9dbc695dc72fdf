// afr-bench-reconstruct: time of one reconstruct() call (display refresh) versus resolution,
// with N = 4 x pixels samples (--spp) in the store, for the CPU backend on 1 and 2 threads and the
// OpenGL backend (whatever driver EGL gives: llvmpipe here). Like a live display, every timed
// refresh first receives 1/60 s worth of new samples (the store turning over once a second)
// and a new tiling, and reprojects everything for a slightly moved camera. Prints a Markdown
// table of medians over repeats, wall time and process CPU time, with a naive 3 x 3 splat as
// a yardstick of the machine's speed.
//   afr-bench-reconstruct --sizes 256,512,1024 --repeats 15
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/image.h>
#include <afr/common/log.h>
#include <afr/common/random.h>
#include <afr/common/rect.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/display/gl_context.h>
#include <afr/display/gl_reconstructor.h>

#include <epoxy/gl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace {

// A floor under a sky, sampled with world positions (so the reconstructor reprojects), and
// colors that vary at several scales.
afr::Sample make_sample(const afr::Camera& camera, afr::Pcg32& rng, afr::ImageExtent size,
                        double time) {
  afr::Sample s;
  s.x = rng.next_float() * float(size.width);
  s.y = rng.next_float() * float(size.height);
  s.time = time;
  const afr::Ray ray = camera.ray(s.x, s.y, size.width, size.height);
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

afr::SampleBatch make_batch(const afr::Camera& camera, afr::Pcg32& rng, afr::ImageExtent size,
                            size_t n, double t0, double t1) {
  afr::SampleBatch b;
  b.fields = afr::kFieldPosition;
  b.samples.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    b.samples.push_back(make_sample(camera, rng, size, t0 + (t1 - t0) * double(i) / double(n)));
  }
  return b;
}

// 16 x 16 pixel tiles with gradients like the sampler's: mostly static, some edges and motion.
afr::TilingSnapshot make_tiling(afr::Pcg32& rng, afr::ImageExtent size, double time, double rate) {
  afr::TilingSnapshot s;
  s.time = time;
  s.region = size.rect();
  for (int y = 0; y < size.height; y += 16) {
    for (int x = 0; x < size.width; x += 16) {
      afr::TileInfo t;
      t.rect = afr::PixelRect{x, y, std::min(x + 16, size.width), std::min(y + 16, size.height)};
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
  double cpu = 0.0;      // median CPU time of the whole process (all its threads) per refresh
  double gpu = 0.0;      // median GPU time per refresh (timer queries); 0 for the CPU backend
  afr::GpuTimes passes;  // median of each pass
  afr::CallTimes call;   // median of each phase of the call (GL backend)
  afr::CpuPhaseTimes cpu_phases;  // median of each phase of the call (CPU backend)
  double sustained = 0.0;         // ms per refresh, back to back, until the last one is finished
};

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// A Markdown table, unless it has no rows: its caption, the header of `columns`, the rows.
void print_table(const std::string& caption, const std::vector<std::string>& columns,
                 const std::vector<std::string>& rows) {
  if (rows.empty()) return;
  fmt::print("\n{}\n\n| {} |\n|", caption, fmt::join(columns, " | "));
  for (size_t k = 0; k < columns.size(); ++k) fmt::print("---|");
  fmt::print("\n");
  for (const std::string& row : rows) fmt::print("{}\n", row);
}

// Each of `fields` of *out: that field's median over `rows`.
template <typename Row>
void median_fields(const std::vector<Row>& rows, std::initializer_list<double Row::*> fields,
                   Row* out) {
  for (double Row::*field : fields) {
    std::vector<double> v;
    for (const Row& r : rows) v.push_back(r.*field);
    out->*field = median_of(v);
  }
}

Timing summarize(std::vector<double> ms, const std::vector<double>& cpu_ms) {
  std::sort(ms.begin(), ms.end());
  const auto at = [&](double q) { return ms[size_t(std::lround(q * double(ms.size() - 1)))]; };
  Timing t;
  t.median = median_of(ms);
  t.p10 = at(0.1);
  t.p90 = at(0.9);
  t.cpu = median_of(cpu_ms);
  t.sustained = t.median;
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
Timing naive_splat(afr::ImageExtent size, int repeats) {
  afr::Pcg32 rng(5);
  const size_t n = 4 * size_t(size.area());
  std::vector<glm::vec2> xy(n);
  std::vector<glm::vec3> color(n);
  for (size_t i = 0; i < n; ++i) {
    xy[i] = glm::vec2(rng.next_float() * float(size.width), rng.next_float() * float(size.height));
    color[i] = glm::vec3(rng.next_float(), rng.next_float(), rng.next_float());
  }
  std::vector<glm::vec4> acc(size_t(size.area()));
  std::vector<double> ms, cpu;
  for (int r = 0; r < repeats; ++r) {
    const double c0 = process_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    std::fill(acc.begin(), acc.end(), glm::vec4(0.0f));
    for (size_t i = 0; i < n; ++i) {
      const int cx = int(xy[i].x), cy = int(xy[i].y);
      for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, size.height - 1); ++y) {
        for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, size.width - 1); ++x) {
          const glm::vec2 d = glm::vec2(float(x) + 0.5f, float(y) + 0.5f) - xy[i];
          const float w = std::exp(-2.0f * glm::dot(d, d));
          acc[size_t(y) * size_t(size.width) + size_t(x)] += glm::vec4(color[i] * w, w);
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

// Keeps each timed image's GPU times once (they arrive a few refreshes late).
void collect(const afr::GpuTimes& g, int warmup, std::vector<afr::GpuTimes>* out) {
  if (g.image > uint64_t(warmup) && (out->empty() || out->back().image < g.image)) {
    out->push_back(g);
  }
}

// What a live display receives, the same for every reconstructor fed: one second of samples
// (N of them), then per refresh 1/60 s of new samples and a new tiling, for a camera that
// moves a little each refresh.
class LiveFeed {
 public:
  LiveFeed(afr::ImageExtent size, size_t n, uint64_t seed)
      : size_(size), n_(n), rng_(afr::mix_seed(seed)) {}

  void fill(std::initializer_list<afr::Reconstructor*> recs) {
    const afr::SampleBatch b = make_batch(camera(0), rng_, size_, n_, 0.0, 1.0);
    for (afr::Reconstructor* r : recs) r->add_batch(b);
  }

  // One refresh's input: its new samples and tiling, the camera and the display time.
  struct Frame {
    afr::SampleBatch batch;
    afr::TilingSnapshot tiling;
    afr::Camera camera;
    double time = 0.0;
  };

  // The next refresh's input, made (not yet delivered).
  Frame make() {
    Frame f;
    f.camera = camera(frame_++);
    f.batch = make_batch(f.camera, rng_, size_, n_ / 60, t_, t_ + 1.0 / 60.0);
    t_ += 1.0 / 60.0;
    f.tiling = make_tiling(rng_, size_, t_, double(n_) / double(size_.area()));  // per px and s
    f.time = t_;
    return f;
  }

  static void deliver(const Frame& f, std::initializer_list<afr::Reconstructor*> recs) {
    for (afr::Reconstructor* r : recs) {
      r->add_batch(f.batch);
      r->set_tiling(f.tiling);
    }
  }

  // The next refresh's samples and tiling into every one of `recs`: its camera, and its
  // display time in *t.
  afr::Camera next(std::initializer_list<afr::Reconstructor*> recs, double* t) {
    const Frame f = make();
    deliver(f, recs);
    *t = f.time;
    return f.camera;
  }

 private:
  static afr::Camera camera(int frame) {
    return afr::Camera::look_at({0.01 * frame, 0.5, -0.01 * frame}, {0.0, 0.0, -5.0}, {0, 1, 0},
                                1.0, 0.01);
  }
  afr::ImageExtent size_;
  size_t n_;
  afr::Pcg32 rng_;
  double t_ = 1.0;
  int frame_ = 0;
};

// Fills the store, then times `repeats` refreshes after `warmup` untimed ones. The refreshes'
// inputs are made first, so that the sustained time (the timed refreshes back to back, until
// the GPU has finished the last, less the delivery of their inputs, which a display's ingest
// thread does meanwhile) holds only the reconstructor: a GPU backend's call returns before the
// GPU is done, so neither the call nor the GPU's time alone is the rate.
Timing run(afr::Reconstructor& rec, afr::ImageExtent size, int repeats, int warmup, bool readback,
           uint64_t seed) {
  LiveFeed feed(size, rec.capacity(), seed);
  feed.fill({&rec});
  std::vector<LiveFeed::Frame> frames;
  for (int frame = 0; frame < warmup + repeats; ++frame) frames.push_back(feed.make());
  std::vector<double> ms, cpu;
  std::vector<afr::GpuTimes> gpu;
  std::vector<afr::CallTimes> calls;
  std::vector<afr::CpuPhaseTimes> cpu_phases;
  afr::Image image;
  using Clock = std::chrono::steady_clock;
  Clock::time_point start;
  Clock::duration delivering{};
  for (int frame = 0; frame < warmup + repeats; ++frame) {
    if (frame == warmup) {
      rec.finish();
      start = Clock::now();
    }
    const auto d0 = Clock::now();
    LiveFeed::deliver(frames[size_t(frame)], {&rec});
    if (frame >= warmup) delivering += Clock::now() - d0;
    const LiveFeed::Frame& f = frames[size_t(frame)];
    const double c0 = process_cpu_ms();
    rec.reconstruct(f.camera, f.time, size.width, size.height, readback ? &image : nullptr);
    if (frame >= warmup) {
      ms.push_back(rec.frame_stats().milliseconds);
      cpu.push_back(process_cpu_ms() - c0);
      calls.push_back(rec.frame_stats().call);
      cpu_phases.push_back(rec.frame_stats().cpu);
    }
    collect(rec.frame_stats().gpu, warmup, &gpu);
  }
  rec.finish();
  const double sustained =
      std::chrono::duration<double, std::milli>(Clock::now() - start - delivering).count() /
      double(repeats);
  collect(rec.frame_stats().gpu, warmup, &gpu);
  Timing timing = summarize(ms, cpu);
  timing.sustained = sustained;
  using afr::CallTimes, afr::CpuPhaseTimes, afr::GpuTimes;
  median_fields(calls,
                {&CallTimes::wait, &CallTimes::copy, &CallTimes::prepare, &CallTimes::upload,
                 &CallTimes::passes},
                &timing.call);
  median_fields(cpu_phases,
                {&CpuPhaseTimes::prepare, &CpuPhaseTimes::shape, &CpuPhaseTimes::reproject,
                 &CpuPhaseTimes::splat, &CpuPhaseTimes::fill},
                &timing.cpu_phases);
  if (!gpu.empty() && gpu.back().timed) {
    std::vector<double> totals;
    for (const afr::GpuTimes& g : gpu) totals.push_back(g.total());
    timing.gpu = median_of(totals);
    median_fields(
        gpu,
        {&GpuTimes::upload, &GpuTimes::bin, &GpuTimes::splat, &GpuTimes::fill, &GpuTimes::readback},
        &timing.passes);
  }
  return timing;
}

// The CPU backend against the yardstick, alternating: each round times `per_round` naive
// splats, then `per_round` refreshes of `rec` (its live feed going on from round to round), so
// that a machine whose speed drifts over seconds (a shared host) slows both alike. Returns each
// round's ratio of medians, and the medians of each side over all rounds.
struct Alternation {
  std::vector<double> ratios;
  std::vector<double> yardstick, backend;  // every timing of each, ms
};

Alternation alternate(afr::Reconstructor& rec, afr::ImageExtent size, int rounds, int per_round,
                      int warmup, bool readback) {
  LiveFeed feed(size, rec.capacity(), 1);
  feed.fill({&rec});
  afr::Image image;
  const auto refresh = [&] {
    double t = 0.0;
    const afr::Camera camera = feed.next({&rec}, &t);
    rec.reconstruct(camera, t, size.width, size.height, readback ? &image : nullptr);
    return rec.frame_stats().milliseconds;
  };
  for (int k = 0; k < warmup; ++k) refresh();
  Alternation out;
  for (int round = 0; round < rounds; ++round) {
    std::vector<double> yardstick, ms;
    for (int k = 0; k < per_round; ++k) yardstick.push_back(naive_splat(size, 1).median);
    for (int k = 0; k < per_round; ++k) ms.push_back(refresh());
    out.ratios.push_back(median_of(ms) / median_of(yardstick));
    out.yardstick.insert(out.yardstick.end(), yardstick.begin(), yardstick.end());
    out.backend.insert(out.backend.end(), ms.begin(), ms.end());
  }
  return out;
}

// The GL backend's image against the CPU backend's for the same samples, tilings and cameras
// (three refreshes after one second of samples): RMS and largest difference of the 8-bit sRGB
// channels, and the share of pixels whose hole-filled state differs.
struct Agreement {
  double rms = 0.0;
  int max = 0;
  double holes = 0.0;  // |GL holes - CPU holes| / pixels
};

Agreement agreement(const afr::ReconstructorConfig& cfg, const std::shared_ptr<afr::EglContext>& gl,
                    afr::GlReconstructorOptions options, int threads) {
  afr::ReconstructorConfig c = cfg;
  c.threads = threads;
  afr::CpuReconstructor cpu(c);
  afr::GlReconstructor gpu(c, gl, options);
  const afr::ImageExtent size = cfg.image;
  LiveFeed feed(size, cpu.capacity(), 7);
  feed.fill({&cpu, &gpu});
  afr::Image a, b;
  for (int frame = 0; frame < 3; ++frame) {
    double t = 0.0;
    const afr::Camera cam = feed.next({&cpu, &gpu}, &t);
    cpu.reconstruct(cam, t, size.width, size.height, &a);
    gpu.reconstruct(cam, t, size.width, size.height, &b);
  }
  Agreement out;
  out.rms = afr::rms_error_255(a, b);
  for (size_t p = 0; p < a.pixels.size(); ++p) {
    for (int k = 0; k < 3; ++k) {
      out.max = std::max(out.max, std::abs(int(afr::linear_to_srgb8(a.pixels[p][k])) -
                                           int(afr::linear_to_srgb8(b.pixels[p][k]))));
    }
  }
  out.holes =
      std::abs(double(gpu.frame_stats().hole_pixels) - double(cpu.frame_stats().hole_pixels)) /
      double(size.area());
  return out;
}

// The gather's tile sides times its chunk sizes; the raster path once.
std::vector<std::pair<int, size_t>> gather_variants(bool gather, const std::vector<int>& tiles,
                                                    const std::vector<size_t>& chunk_mibs) {
  if (!gather) return {{16, 0}};
  std::vector<std::pair<int, size_t>> v;
  for (const int tile : tiles) {
    for (const size_t chunk : chunk_mibs) v.emplace_back(tile, chunk);
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-reconstruct: reconstruction time vs resolution, CPU and OpenGL"};
  std::vector<std::string> size_texts{"256", "512", "1024"};
  std::vector<int> thread_counts{1, 2};
  std::vector<std::string> splat_texts{"gather", "raster"};
  std::vector<int> tiles{16};
  std::vector<size_t> chunk_mibs{256};
  std::vector<std::string> probe_texts{"none"};
  std::string backends = "cpu,gl";
  std::string mode_text = "adaptive", log_level = "warn";
  int repeats = 15, warmup = 3, gl_repeats = 7, gpu = -1, spp = 4, rounds = 0, per_round = 5;
  float shrink_above = afr::SplatSizeRule{}.shrink_above;
  bool readback = true, naive = true, gl_debug = false, check = false, sync_passes = false;
  app.add_option("--sizes", size_texts, "outputs, comma separated: S (square) or WxH")
      ->delimiter(',');
  app.add_option("--threads", thread_counts, "CPU backend thread counts, comma separated")
      ->delimiter(',');
  app.add_option("--backends", backends, "cpu, gl or cpu,gl");
  app.add_option("--mode", mode_text, "adaptive, adaptive-no-reprojection or frameless");
  app.add_option("--repeats", repeats, "timed refreshes per CPU row")->check(CLI::Range(1, 10000));
  app.add_option("--gl-repeats", gl_repeats, "timed refreshes per GL row")
      ->check(CLI::Range(1, 10000));
  app.add_option("--warmup", warmup, "untimed refreshes first")->check(CLI::Range(0, 10000));
  app.add_option("--readback", readback, "read the image back to memory (GL) / fill it (CPU)");
  app.add_option("--naive", naive, "also time the naive 3x3 splat yardstick");
  app.add_option("--alternate", rounds,
                 "also time each CPU row against the yardstick in this many alternating rounds "
                 "(--per-round of each per round)")
      ->check(CLI::Range(0, 10000));
  app.add_option("--per-round", per_round,
                 "yardstick splats and refreshes per round of --alternate")
      ->check(CLI::Range(1, 1000));
  app.add_option("--gpu", gpu, "EGL device for the GL backend (-1: hardware first)")
      ->check(CLI::Range(-1, 63));
  app.add_option("--gl-splat", splat_texts,
                 "GL splat passes to time, comma separated: gather, raster (auto: the "
                 "device's own)")
      ->delimiter(',');
  app.add_option("--gl-tiles", tiles, "gather tile sides to time, comma separated (4, 8, 16)")
      ->delimiter(',');
  app.add_option("--gl-chunks", chunk_mibs,
                 "gather chunk sizes to time, MiB of splat records a pass reads (0: one pass)")
      ->delimiter(',');
  app.add_option("--gl-probes", probe_texts,
                 "GL splat passes with part of their work left out, also timed, comma "
                 "separated: culled, flat, dots (raster), visit (gather); none: the real passes")
      ->delimiter(',');
  app.add_option("--spp", spp, "samples stored per pixel: N = spp x pixels")
      ->check(CLI::Range(1, 64));
  app.add_option("--shrink-above", shrink_above,
                 "coverage map: splats shrink where more splats than this reached a pixel")
      ->check(CLI::Range(4.0, 1024.0));
  app.add_flag("--gl-debug", gl_debug,
               "a debug GL context; the driver's messages are logged (with --log debug)");
  app.add_flag("--gl-sync-passes", sync_passes,
               "a software rasteriser: wait for each GL pass and time it on the CPU (its timer "
               "queries measure nothing); the passes then no longer overlap");
  app.add_flag("--check", check,
               "also compare each GL row's image with the CPU backend's (8-bit sRGB RMS, max)");
  app.add_option("--log", log_level, "log level");
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging(log_level);
    const afr::ReconstructionMode mode = afr::parse_mode(mode_text);
    std::vector<afr::ImageExtent> sizes;
    for (const std::string& text : size_texts) {
      sizes.push_back(text.find('x') == std::string::npos ? afr::parse_image_size(text + "x" + text)
                                                          : afr::parse_image_size(text));
    }
    std::string gl_error;
    std::shared_ptr<afr::EglContext> gl;
    if (backends.find("gl") != std::string::npos) {
      gl = afr::EglContext::create_headless(afr::HeadlessGlOptions{gpu, gl_debug}, &gl_error);
      if (!gl) fmt::print(stderr, "OpenGL backend skipped: {}\n", gl_error);
    }
    fmt::print(
        "Reconstruction, mode {}, N = {} x pixels, 1/60 of N new samples per refresh, "
        "median of {} (CPU) / {} (GL) refreshes{}; refreshes/s: the timed refreshes back to "
        "back until the last is finished, their inputs' delivery not counted\n",
        afr::mode_name(mode), spp, repeats, gl_repeats, readback ? ", image read back" : "");
    if (gl) {
      GLint64 block = 0;
      glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &block);
      fmt::print("OpenGL: {} on {}, {}, largest storage block {} MiB\n", gl->renderer(),
                 gl->device(), gl->version(), block >> 20);
    }
    fmt::print(
        "\n| backend | threads | resolution | N | call ms | p10 ms | p90 ms | CPU ms | GPU ms | "
        "refreshes/s |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
    std::vector<afr::GlSplat> splats;
    for (const std::string& text : splat_texts) splats.push_back(afr::parse_gl_splat(text));
    std::vector<afr::GlProbe> probes;
    for (const std::string& text : probe_texts) probes.push_back(afr::parse_gl_probe(text));
    std::vector<std::string> passes, phases, cpu_phases, checks, alternations;
    for (const afr::ImageExtent size : sizes) {
      afr::ReconstructorConfig cfg;
      cfg.image = size;
      cfg.mode = mode;
      const size_t n = size_t(spp) * size_t(size.area());
      cfg.capacity = n;
      cfg.splat.shrink_above = shrink_above;
      const auto row = [&](const std::string& backend, const std::string& threads, Timing t) {
        // A GPU backend's call returns before the GPU is done (unless it reads the image
        // back): the rate is the refreshes back to back, until the GPU has finished.
        const double bound = t.sustained;
        fmt::print("| {} | {} | {}x{} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {} | {:.0f} |\n",
                   backend, threads, size.width, size.height, n, t.median, t.p10, t.p90, t.cpu,
                   t.gpu > 0.0 ? fmt::format("{:.2f}", t.gpu) : std::string("-"), 1000.0 / bound);
        std::fflush(stdout);
      };
      if (naive) row("naive 3x3 splat (yardstick)", "1", naive_splat(size, repeats));
      if (backends.find("cpu") != std::string::npos) {
        for (int threads : thread_counts) {
          cfg.threads = threads;
          afr::CpuReconstructor rec(cfg);
          const Timing t = run(rec, size, repeats, warmup, readback, 1);
          row("cpu", std::to_string(threads), t);
          const afr::CpuPhaseTimes& p = t.cpu_phases;
          cpu_phases.push_back(fmt::format(
              "| {} | {}x{} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |", threads, size.width,
              size.height, p.prepare, p.shape, p.reproject, p.splat, p.fill));
          if (rounds > 0) {
            afr::CpuReconstructor fresh(cfg);
            const Alternation a = alternate(fresh, size, rounds, per_round, warmup, readback);
            // Each side's fastest tenth: on a shared host the least disturbed timings.
            const auto p10 = [](std::vector<double> v) {
              std::sort(v.begin(), v.end());
              return v[size_t(std::lround(0.1 * double(v.size() - 1)))];
            };
            std::vector<double> r = a.ratios;
            std::sort(r.begin(), r.end());
            const auto at = [&](double q) {
              return r[size_t(std::lround(q * double(r.size() - 1)))];
            };
            alternations.push_back(fmt::format(
                "| {} | {}x{} | {} x {} | {:.2f} | {:.2f} | {:.3f} | {:.3f} - {:.3f} | {:.2f} | "
                "{:.2f} | {:.3f} |",
                threads, size.width, size.height, rounds, per_round, median_of(a.yardstick),
                median_of(a.backend), median_of(a.ratios), at(0.1), at(0.9), p10(a.yardstick),
                p10(a.backend), p10(a.backend) / p10(a.yardstick)));
          }
        }
      }
      if (gl) {
        for (const afr::GlSplat splat : splats) {
          const bool gather = splat == afr::GlSplat::kGather;
          for (const auto& [tile, chunk] : gather_variants(gather, tiles, chunk_mibs)) {
            for (const afr::GlProbe probe : probes) {
              // Each probe of this splat pass (a probe of the other pass is not run).
              if (!afr::gl_probe_fits(probe, splat)) continue;
              afr::GlReconstructorOptions options{splat, tile, chunk << 20, sync_passes, probe};
              // "gl gather TILE" (the chunk size named only when several are timed), and the
              // probe: "gl raster (culled)"
              std::string name = gather ? fmt::format("gl gather {}", tile) : "gl raster";
              if (gather && chunk_mibs.size() > 1) name += fmt::format(" / {} MiB", chunk);
              if (probe != afr::GlProbe::kNone)
                name += fmt::format(" ({})", afr::gl_probe_name(probe));
              std::unique_ptr<afr::GlReconstructor> made;
              try {
                made = std::make_unique<afr::GlReconstructor>(cfg, gl, options);
              } catch (const afr::Error& e) {
                // A path this driver cannot run at this size (the store larger than its largest
                // storage block): the row says why, and the others run.
                fmt::print("| {} | - | {}x{} | {} | skipped: {} | | | | | |\n", name, size.width,
                           size.height, n, e.what());
                continue;
              }
              afr::GlReconstructor& rec = *made;
              const Timing t = run(rec, size, gl_repeats, warmup, readback, 1);
              row(name, "-", t);
              phases.push_back(
                  fmt::format("| {} | {}x{} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |", name,
                              size.width, size.height, t.call.wait, t.call.copy, t.call.prepare,
                              t.call.upload, t.call.passes));
              // A probe's image is wrong by design: nothing to compare.
              if (check && probe == afr::GlProbe::kNone) {
                const Agreement ag =
                    agreement(cfg, gl, options, int(std::thread::hardware_concurrency()));
                checks.push_back(fmt::format("| {} | {}x{} | {:.3f} | {} | {:.4f} |", name,
                                             size.width, size.height, ag.rms, ag.max, ag.holes));
              }
              if (t.gpu > 0.0)
                passes.push_back(fmt::format(
                    "| {} | {}x{} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |", name,
                    size.width, size.height, t.passes.upload, t.passes.bin, t.passes.splat,
                    t.passes.fill, t.passes.readback, t.gpu));
            }
          }
        }
      }
    }
    print_table(
        "The CPU backend against the yardstick in alternating rounds (each round: the naive "
        "splat, then as many refreshes of the backend): the medians of all their timings, the "
        "median over the rounds of a round's ratio (backend median / yardstick median) and its "
        "p10 - p90, and each side's p10 (the least disturbed timings) and their ratio",
        {"threads", "resolution", "rounds x per round", "yardstick ms", "cpu ms", "ratio of rounds",
         "its p10 - p90", "yardstick p10 ms", "cpu p10 ms", "ratio of p10s"},
        alternations);
    print_table(
        "The CPU backend's call by phase, median wall ms (prepare: new samples, tile field, "
        "filters; shape: each pixel's splat shape; reproject: every sample projected into its "
        "bin; splat: the Gaussian splats; fill: normalisation and holes)",
        {"threads", "resolution", "prepare", "shape", "reproject", "splat", "fill"}, cpu_phases);
    const bool waited = gl && gl->software() && sync_passes;
    if (gl && gl->software() && !sync_passes) {
      fmt::print(
          "\nNo GPU times: {} runs the work when it is waited for, so its timer queries "
          "measure nothing; with at most three images in flight its call ms measure its rate "
          "(--gl-sync-passes times each pass).\n",
          gl->renderer());
    }
    print_table(waited ? fmt::format("Time per pass, median ms, each pass waited for (glFinish) "
                                     "and timed on the CPU (--gl-sync-passes: {} has no timer "
                                     "queries); the image is their sum",
                                     gl->renderer())
                       : "GPU time per pass, median ms (GL_TIME_ELAPSED; a pass's time can "
                         "include the tail of the image before it), and of the whole image "
                         "(GL_TIMESTAMP, from the moment the image before it was done)",
                {"backend", "resolution", "upload", "bin", "splat", "fill", "read-back", "image"},
                passes);
    print_table(
        "The GL backend's call by phase, median wall ms on the calling thread (wait: for an "
        "image slot and any read-back; copy: new samples out of the store; prepare: counts, tile "
        "field, filters; upload: into the staging ring; passes: the commands)",
        {"backend", "resolution", "wait", "copy", "prepare", "upload", "passes"}, phases);
    print_table("The GL image against the CPU backend's, same samples (8-bit sRGB levels)",
                {"backend", "resolution", "RMS", "max", "hole pixels differing"}, checks);
  } catch (const afr::Error& e) {
    fmt::print(stderr, "afr-bench-reconstruct: {}\n", e.what());
    return 1;
  }
  return 0;
}
