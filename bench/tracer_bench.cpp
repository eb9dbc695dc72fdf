// afr-bench-tracer: throughput of the tracer (shaded samples/s and rays/s) on the built-in
// scene, on a glTF scene and on a deforming sheet (a skinned and morphed grid made here), for
// single rays at random image positions and for crosshairs cast as five single rays or as one
// 8-wide packet, on 1 and 2 threads, at several animation times. Prints a Markdown table of
// medians over repeats, and for the deforming sheet what set_time costs and the samples/s of a
// sampler on it, with its scene time moving at every animation step and almost never; with
// --forest, a forest of copies of one mesh held as world-space copies and as instances.
//   afr-bench-tracer --scene ../shared/scenes/bart-kitchen/kitchen.gltf --times 0,5,10
//   afr-bench-tracer --no-builtin --deforming 256
//   afr-bench-tracer --no-builtin --forest 16 --forest 256 --forest 4096
#include <afr/common/builtin_scene.h>
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>
#include <afr/common/random.h>
#include <afr/sampler/sampler_pool.h>
#include <afr/sampler/tracer.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
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

// The sun of the scenes made here: a directional light shining along (0.3, -1, -0.4) and the
// node that carries it. Returns the node.
int add_sun(afr::Scene* s) {
  afr::Light sun;
  sun.type = afr::Light::Type::kDirectional;
  sun.intensity = 3.0f;
  s->lights.push_back(sun);
  afr::Node node;
  node.light = int(s->lights.size()) - 1;
  node.rotation =
      glm::quatLookAt(glm::normalize(glm::dvec3(0.3, -1.0, -0.4)), glm::dvec3(0.0, 1.0, 0.0));
  s->nodes.push_back(node);
  return int(s->nodes.size()) - 1;
}

// ---- The deforming sheet ----
//
// An n x n grid of vertices over [-2, 2] x [-2, 2] in the XZ plane, skinned to a chain of
// kSheetJoints joints along X that wave about Z, with one morph target (a ripple, with its
// normals) whose weight rises and falls: every vertex moves at every time. Lit by a sun, seen
// from above and in front; its animation is 4 s long.
constexpr int kSheetJoints = 8;
constexpr double kSheetSeconds = 4.0;

afr::Scene make_deforming_sheet(int n) {
  afr::Scene s;
  s.source = fmt::format("deforming sheet {}x{}", n, n);
  afr::Material grey;
  grey.base_color_factor = glm::vec4(0.7f, 0.7f, 0.7f, 1.0f);
  grey.metallic = 0.0f;
  grey.roughness = 0.6f;
  s.materials.push_back(grey);

  afr::Primitive p;
  p.material = 0;
  afr::MorphTarget ripple;
  const float step = 4.0f / float(n - 1);
  const float joint_step = 4.0f / float(kSheetJoints - 1);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float x = -2.0f + step * float(i), z = -2.0f + step * float(j);
      p.positions.push_back({x, 0.0f, z});
      p.normals.push_back({0.0f, 1.0f, 0.0f});
      // y = 0.2 sin(3x) cos(3z), and its normal's change (-dy/dx, 0, -dy/dz).
      ripple.positions.push_back({0.0f, 0.2f * std::sin(3.0f * x) * std::cos(3.0f * z), 0.0f});
      ripple.normals.push_back({-0.6f * std::cos(3.0f * x) * std::cos(3.0f * z), 0.0f,
                                0.6f * std::sin(3.0f * x) * std::sin(3.0f * z)});
      // The two joints around x, weighted by distance.
      const float f = (x + 2.0f) / joint_step;
      const int k = std::min(int(f), kSheetJoints - 2);
      const float w = std::clamp(f - float(k), 0.0f, 1.0f);
      p.joints.push_back({uint16_t(k), uint16_t(k + 1), 0, 0});
      p.joint_weights.push_back({1.0f - w, w, 0.0f, 0.0f});
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const uint32_t a = uint32_t(j * n + i), b = a + 1, c = a + uint32_t(n), d = c + 1;
      p.indices.insert(p.indices.end(), {a, c, b, b, c, d});  // faces +Y
    }
  }
  p.targets.push_back(std::move(ripple));
  afr::Mesh mesh;
  mesh.name = "sheet";
  mesh.primitives.push_back(std::move(p));
  mesh.weights = {0.5f};
  s.meshes.push_back(std::move(mesh));

  // Node 0: the sheet. Nodes 1..kSheetJoints: the joint chain, each a child of the one before.
  afr::Node sheet;
  sheet.mesh = 0;
  sheet.skin = 0;
  s.nodes.push_back(sheet);
  afr::Skin skin;
  for (int k = 0; k < kSheetJoints; ++k) {
    afr::Node joint;
    joint.translation = k == 0 ? glm::dvec3(-2.0, 0.0, 0.0) : glm::dvec3(joint_step, 0.0, 0.0);
    if (k + 1 < kSheetJoints) joint.children = {int(s.nodes.size()) + 1};
    skin.joints.push_back(int(s.nodes.size()));
    skin.inverse_bind_matrices.push_back(
        glm::translate(glm::dmat4(1.0), glm::dvec3(2.0 - joint_step * k, 0.0, 0.0)));
    s.nodes.push_back(joint);
  }
  s.skins.push_back(std::move(skin));
  const int camera = int(s.nodes.size());
  afr::Node eye;
  eye.camera = 0;
  eye.translation = {0.0, 3.0, 4.5};
  eye.rotation =
      glm::quatLookAt(glm::normalize(glm::dvec3(0.0, -3.0, -4.5)), glm::dvec3(0.0, 1.0, 0.0));
  s.nodes.push_back(eye);
  s.cameras.push_back(afr::CameraModel{"eye", 0.8, 0.01});
  add_sun(&s);
  s.roots = {0, 1, camera, camera + 1};
  s.ambient = glm::vec3(0.1f);

  // Each joint but the root waves about Z, a phase apart; the ripple comes and goes.
  constexpr int kKeys = 41;
  for (int k = 1; k < kSheetJoints; ++k) {
    afr::AnimationChannel wave;
    wave.node = 1 + k;
    wave.path = afr::AnimatedPath::kRotation;
    for (int key = 0; key < kKeys; ++key) {
      const double t = kSheetSeconds * key / (kKeys - 1);
      const double angle = 0.15 * std::sin(2.0 * M_PI * t / kSheetSeconds + 0.7 * k);
      wave.times.push_back(t);
      wave.values.push_back({0.0, 0.0, std::sin(0.5 * angle), std::cos(0.5 * angle)});
    }
    s.channels.push_back(std::move(wave));
  }
  afr::AnimationChannel weights;
  weights.node = 0;
  weights.path = afr::AnimatedPath::kWeights;
  weights.weight_count = 1;
  weights.times = {0.0, 0.5 * kSheetSeconds, kSheetSeconds};
  weights.weights = {0.0, 1.0, 0.0};
  s.channels.push_back(std::move(weights));
  s.finalize();
  return s;
}

// Counts samples and the scene times they were traced at (a batch's samples come from one
// sampler thread, in time order).
struct CountingSink final : afr::SampleSink {
  std::atomic<uint64_t> samples{0};
  std::atomic<uint64_t> scene_times{0};
  double last_time = -1.0;
  void on_batch(afr::SampleBatch&& b) override {
    samples += b.samples.size();
    for (const afr::Sample& s : b.samples) {
      if (s.time != last_time) ++scene_times;
      last_time = s.time;
    }
  }
  void on_tiling(afr::TilingSnapshot&&) override {}
};

struct SamplerRun {
  double samples_per_s = 0.0;
  double scene_times_per_s = 0.0;  // distinct scene times the samples were traced at
};

// A one-thread sampler pool on the wall clock, as a sampler node runs it, over `seconds` after
// the first fill.
SamplerRun run_sampler(const afr::Scene& scene, int width, int height, double animation_step,
                       double seconds) {
  afr::WallClock clock;
  CountingSink sink;
  afr::SamplerConfig config;
  config.image = {width, height};
  config.animation_step = animation_step;
  afr::SamplerPoolOptions options;
  options.threads = 1;
  afr::SamplerPool pool(scene, config, options, clock, sink);
  pool.start();
  std::this_thread::sleep_for(std::chrono::duration<double>(0.3));
  const uint64_t s0 = sink.samples, n0 = sink.scene_times;
  const auto t0 = Clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const uint64_t s1 = sink.samples, n1 = sink.scene_times;
  const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
  pool.stop();
  return {double(s1 - s0) / dt, double(n1 - n0) / dt};
}

// A forest: `copies` copies of one tree (a sphere of 33 x 65 = 2,145 vertices) on a square grid
// over a floor, each turned and stretched its own way, as EXT_mesh_gpu_instancing places them;
// a camera looking over them and the sun. Static: what differs is only how the tracer holds
// the copies (TracerOptions::max_copied_vertices).
afr::Scene make_forest(int copies) {
  afr::Scene s;
  s.source = fmt::format("forest of {}", copies);
  afr::Material leaves, ground;
  leaves.base_color_factor = glm::vec4(0.2f, 0.6f, 0.25f, 1.0f);
  leaves.roughness = 0.8f;
  ground.base_color_factor = glm::vec4(0.5f, 0.45f, 0.4f, 1.0f);
  s.materials = {leaves, ground};
  afr::Primitive tree;
  constexpr int kRings = 32, kSegments = 64;
  for (int i = 0; i <= kRings; ++i) {
    const double theta = M_PI * i / kRings;
    for (int j = 0; j <= kSegments; ++j) {
      const double phi = 2.0 * M_PI * j / kSegments;
      const glm::vec3 n(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
                        float(std::sin(theta) * std::sin(phi)));
      tree.positions.push_back(0.5f * n + glm::vec3(0.0f, 0.5f, 0.0f));
      tree.normals.push_back(n);
    }
  }
  for (int i = 0; i < kRings; ++i) {
    for (int j = 0; j < kSegments; ++j) {
      const uint32_t a = uint32_t(i * (kSegments + 1) + j), b = a + 1;
      const uint32_t c = a + uint32_t(kSegments + 1), d = c + 1;
      tree.indices.insert(tree.indices.end(), {a, b, c, b, d, c});
    }
  }
  tree.material = 0;
  const int side = std::max(1, int(std::ceil(std::sqrt(double(copies)))));
  const float extent = 1.2f * float(side);
  afr::Primitive floor;
  floor.positions = {
      {-extent, 0, -extent}, {extent, 0, -extent}, {extent, 0, extent}, {-extent, 0, extent}};
  floor.normals.assign(4, glm::vec3(0, 1, 0));
  floor.indices = {0, 2, 1, 0, 3, 2};
  floor.material = 1;
  s.meshes.resize(2);
  s.meshes[0].primitives.push_back(std::move(tree));
  s.meshes[1].primitives.push_back(std::move(floor));
  afr::Node ground_node;
  ground_node.mesh = 1;
  s.nodes.push_back(ground_node);
  s.roots.push_back(0);
  afr::Pcg32 random(7);
  for (int k = 0; k < copies; ++k) {
    afr::Node copy;
    copy.mesh = 0;
    copy.translation = {2.4 * (k % side) - extent + 1.2, 0.0, 2.4 * (k / side) - extent + 1.2};
    copy.rotation = glm::angleAxis(2.0 * M_PI * random.next_double(), glm::dvec3(0, 1, 0));
    copy.scale = glm::dvec3(1.0 + random.next_double(), 1.0 + 2.0 * random.next_double(), 1.0);
    s.roots.push_back(int(s.nodes.size()));
    s.nodes.push_back(copy);
  }
  afr::Node eye;
  eye.camera = 0;
  eye.translation = {0.0, 0.3 * extent + 2.0, extent + 2.0};
  eye.rotation = glm::quatLookAt(glm::normalize(-eye.translation), glm::dvec3(0.0, 1.0, 0.0));
  s.cameras.push_back(afr::CameraModel{"eye", 0.8, 0.01});
  s.roots.push_back(int(s.nodes.size()));
  s.nodes.push_back(eye);
  s.roots.push_back(add_sun(&s));
  s.ambient = glm::vec3(0.1f);
  s.finalize();
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-tracer: tracer throughput (shaded samples/s, rays/s)"};
  std::string scene_path, size_text = "640x480", times_text = "0,2.5,5,7.5", log_level = "warn";
  uint64_t samples = 200000, seed = 1;
  int repeats = 5, max_threads = 2, deforming = 0, embree_threads = 0;
  std::vector<int> forests;
  double sampler_seconds = 2.0;
  bool skip_builtin = false;
  app.add_option("--scene", scene_path, "a glTF scene (e.g. the converted BART kitchen)")
      ->check(CLI::ExistingFile);
  app.add_flag("--no-builtin", skip_builtin, "skip the built-in scene");
  app.add_option("--deforming", deforming,
                 "also measure a deforming sheet of N x N vertices (skinned and morphed), and a "
                 "sampler on it; 0 = not")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  app.add_option("--forest", forests,
                 "also compare a forest of N copies of one 2,145-vertex mesh copied into world "
                 "space and instanced (TracerOptions::max_copied_vertices), for each N given")
      ->check(CLI::Range(1, 1 << 20));
  app.add_option("--sampler-seconds", sampler_seconds,
                 "wall seconds of each sampler run on the deforming sheet")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 600.0));
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
  app.add_option("--embree-threads", embree_threads,
                 "threads of the scenes' tracers' BVH builds and commits "
                 "(TracerOptions::embree_threads; 0 = Embree's default)")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
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
    if (deforming > 0) scenes.push_back(make_deforming_sheet(std::max(deforming, 2)));
    std::vector<std::string> names;
    for (const afr::Scene& s : scenes)
      names.push_back(std::filesystem::path(s.source).filename().string());

    fmt::print(
        "## afr-bench-tracer\n\n{}x{} image, {} samples per run, median of {} runs, "
        "{} hardware threads\n\n",
        size.width, size.height, samples, repeats, std::thread::hardware_concurrency());
    if (!scenes.empty()) {
      fmt::print("| scene | triangles | build (ms) | set_time (ms) |\n|---|---:|---:|---:|\n");
    }
    std::vector<std::array<std::unique_ptr<afr::Tracer>, 2>> tracers;
    for (const afr::Scene& scene : scenes) {
      afr::TracerOptions single, packet;
      single.embree_threads = packet.embree_threads = embree_threads;
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
    for (const int copies : forests) {
      const afr::Scene forest = make_forest(copies);
      fmt::print(
          "\n## Forest of {} copies of one mesh (2,145 vertices each)\n\nrandom rays, 1 "
          "thread, median of {} runs, interleaved\n\n| held as | build (ms) | vertices copied "
          "| set_time (ms) | samples/s |\n|---|---:|---:|---:|---:|\n",
          copies, repeats);
      std::array<std::unique_ptr<afr::Tracer>, 2> tracer;
      std::array<double, 2> build_ms{};
      for (int k : {0, 1}) {
        afr::TracerOptions options;
        options.embree_threads = embree_threads;
        options.max_copied_vertices = k == 0 ? std::numeric_limits<size_t>::max() : 0;
        const auto t0 = Clock::now();
        tracer[size_t(k)] = std::make_unique<afr::Tracer>(forest, options);
        build_ms[size_t(k)] = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      }
      std::array<double, 2> set_ms{};
      for (size_t k = 0; k < 2; ++k) {
        const int kSetTimes = 20;
        const auto t0 = Clock::now();
        for (int i = 0; i < kSetTimes; ++i) tracer[k]->set_time(0.01 * i);
        set_ms[k] =
            std::chrono::duration<double, std::milli>(Clock::now() - t0).count() / kSetTimes;
      }
      std::array<std::vector<double>, 2> rates;
      for (int r = 0; r < repeats; ++r) {
        for (size_t k = 0; k < 2; ++k) {
          rates[k].push_back(run_once(*tracer[k], Mode::kRandomRays, 1, size.width, size.height,
                                      samples, seed + uint64_t(r))
                                 .samples_per_s);
        }
      }
      for (size_t k = 0; k < 2; ++k) {
        fmt::print("| {} | {:.0f} | {} | {:.3f} | {} |\n", k == 0 ? "copies" : "instances",
                   build_ms[k], tracer[k]->copied_vertices(), set_ms[k], si(median(rates[k])));
      }
      std::fflush(stdout);
    }
    if (deforming > 0) {
      // The sampler on the animated sheet, moving to a new scene time at every animation step
      // (1 ms, or 8 times what the last move took), and with a step of 1 s: the same scene and
      // sampler with almost no deformation. Their ratio is what deforming costs it.
      const int n = std::max(deforming, 2);
      const afr::Scene& animated = scenes.back();
      afr::Tracer tracer(animated);
      // set_time's parts, by the thread's CPU time: the scene's evaluation, one deformation of
      // the sheet's vertices with and without normals, and the whole call.
      const int kCalls = 50;
      afr::SceneState state;
      auto per_call_ms = [&](auto&& f) {
        const double start = thread_cpu_seconds();
        for (int i = 0; i < kCalls; ++i) f(i);
        return 1e3 * (thread_cpu_seconds() - start) / kCalls;
      };
      const double evaluate_ms = per_call_ms([&](int i) { animated.evaluate(0.013 * i, &state); });
      std::vector<glm::vec3> positions(size_t(n) * size_t(n)), normals(positions.size());
      const double deform_ms =
          per_call_ms([&](int) { animated.deform(0, 0, state, positions.data(), normals.data()); });
      const double deform_positions_ms =
          per_call_ms([&](int) { animated.deform(0, 0, state, positions.data(), nullptr); });
      const double set_time_ms = per_call_ms([&](int i) { tracer.set_time(0.013 * i); });
      // Embree may refit on worker threads too: the call's wall time beside.
      const auto wall_start = Clock::now();
      for (int i = 0; i < kCalls; ++i) tracer.set_time(0.013 * i + 0.005);
      const double set_time_wall_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - wall_start).count() / kCalls;
      const double per_vertex_ns = 1e6 / (double(n) * double(n));
      fmt::print(
          "\n## Deforming sheet\n\n{}x{} vertices ({} triangles), skinned to {} joints with one "
          "morph target; CPU time of one thread\n\n| step | ms | ns per vertex |\n"
          "|---|---:|---:|\n| Scene::evaluate | {:.3f} | |\n"
          "| Scene::deform, positions and normals | {:.3f} | {:.1f} |\n"
          "| Scene::deform, positions | {:.3f} | {:.1f} |\n"
          "| Tracer::set_time (three deformations, velocities, refit) | {:.3f} | {:.1f} |\n"
          "| Tracer::set_time, wall time | {:.3f} | {:.1f} |\n\n",
          n, n, animated.triangle_count(), kSheetJoints, evaluate_ms, deform_ms,
          deform_ms * per_vertex_ns, deform_positions_ms, deform_positions_ms * per_vertex_ns,
          set_time_ms, set_time_ms * per_vertex_ns, set_time_wall_ms,
          set_time_wall_ms * per_vertex_ns);
      fmt::print("A sampler, one thread, {}x{}, on the wall clock:\n\n", size.width, size.height);
      std::vector<double> moving, rare, moving_times, rare_times;
      for (int r = 0; r < std::min(repeats, 3); ++r) {
        const SamplerRun a = run_sampler(animated, size.width, size.height, 1e-3, sampler_seconds);
        const SamplerRun b = run_sampler(animated, size.width, size.height, 1.0, sampler_seconds);
        moving.push_back(a.samples_per_s);
        moving_times.push_back(a.scene_times_per_s);
        rare.push_back(b.samples_per_s);
        rare_times.push_back(b.scene_times_per_s);
      }
      fmt::print("| animation_step | samples/s | scene times/s |\n|---|---:|---:|\n");
      fmt::print("| 1 ms (the default; at least 8 x set_time) | {} | {:.0f} |\n",
                 si(median(moving)), median(moving_times));
      fmt::print("| 1 s (almost no deformation) | {} | {:.1f} |\n\n", si(median(rare)),
                 median(rare_times));
      std::fflush(stdout);
    }
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
