#include <afr/sampler/sampler_pool.h>

#include <afr/common/error.h>
#include <afr/common/region_split.h>

#include <fmt/format.h>

#include <spdlog/spdlog.h>

#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <mutex>
#include <optional>

namespace afr {

namespace {

// How far behind its capped schedule a worker may be (SamplerPool::run).
constexpr double kMaxCatchUpSeconds = 0.05;

// A worker's view of the shared clock: the sampler tells its clock about traced rays, which
// only matters for virtual clocks; a live pool shares one read-only wall clock.
class SharedClock final : public Clock {
 public:
  explicit SharedClock(const Clock& clock) : clock_(clock) {}
  double now() const override { return clock_.now(); }

 private:
  const Clock& clock_;
};

}  // namespace

struct SamplerPool::Worker {
  std::unique_ptr<Tracer> tracer;
  std::unique_ptr<SharedClock> clock;
  std::unique_ptr<Sampler> sampler;
  std::thread thread;
  mutable std::mutex counters_mutex;
  SamplerCounters counters;  // copied from the sampler every few steps
  // A region the worker is to move to at its next step (set_region).
  std::atomic<bool> region_changed{false};
  std::mutex region_mutex;
  std::optional<PixelRect> next_region;
};

SamplerPool::SamplerPool(const Scene& scene, const SamplerConfig& config,
                         const SamplerPoolOptions& options, const Clock& clock, SampleSink& sink)
    : scene_(scene), config_(config), options_(options), clock_(clock), sink_(sink) {
  config_.validate();
  if (options.threads < 1 || options.threads > 256) {
    throw Error(fmt::format("sampler threads: {} is outside 1..256", options.threads));
  }
  if (!(options.max_samples_per_second >= 0.0)) {
    throw Error(
        fmt::format("samples-per-second cap {} is negative", options.max_samples_per_second));
  }
  const PixelRect owned = config_.owned_region();
  if (owned.area() < options.threads) {
    throw Error(fmt::format("region of {} pixels is too small for {} threads", owned.area(),
                            options.threads));
  }
  region_ = owned;
  regions_ = split_region(owned, std::vector<double>(size_t(options.threads), 1.0));
  for (int t = 0; t < options.threads; ++t) {
    auto w = std::make_unique<Worker>();
    SamplerConfig c = config_;
    c.region = regions_[t];
    c.seed = config_.seed + uint64_t(t) * 0x9e3779b97f4a7c15ULL;
    // One build of the scene's BVHs (or the caller's, options.geometry); the other threads'
    // tracers share it (Tracer::ShareGeometry). The pool's scene outlives it (the samplers read
    // it too), so the tracer holds it, not a copy of it.
    if (t > 0 || options.geometry) {
      const Tracer& from = t > 0 ? *workers_[0]->tracer : *options.geometry;
      w->tracer = std::make_unique<Tracer>(from, Tracer::ShareGeometry{});
    } else {
      w->tracer = std::make_unique<Tracer>(
          std::shared_ptr<const Scene>(std::shared_ptr<void>(), &scene_), options.tracer);
    }
    w->clock = std::make_unique<SharedClock>(clock_);
    w->sampler = std::make_unique<Sampler>(scene_, *w->tracer, *w->clock, c, sink_);
    workers_.push_back(std::move(w));
  }
}

SamplerPool::~SamplerPool() { stop(); }

void SamplerPool::set_camera_source(const CameraSource* source) {
  for (auto& w : workers_) w->sampler->set_camera_source(source);
}

void SamplerPool::set_region(const PixelRect& region) {
  const ImageExtent image = config_.image;
  if (region.empty() || intersect(region, image.rect()) != region) {
    throw Error(fmt::format("region [{}, {}) x [{}, {}) is not a non-empty part of the {}x{} image",
                            region.x0, region.x1, region.y0, region.y1, image.width, image.height));
  }
  if (region.area() < int64_t(workers_.size())) {
    throw Error(fmt::format("region of {} pixels is too small for {} threads", region.area(),
                            workers_.size()));
  }
  if (region == region_) return;
  const size_t n = workers_.size();
  const std::vector<PixelRect> parts = split_region(region, std::vector<double>(n, 1.0));
  // Greedily, the worker and part that share the most pixels first; ties by index, so the
  // assignment is reproducible.
  struct Pair {
    int64_t shared;
    size_t worker, part;
  };
  std::vector<Pair> pairs;
  pairs.reserve(n * n);
  for (size_t w = 0; w < n; ++w) {
    for (size_t p = 0; p < n; ++p) pairs.push_back({intersect(regions_[w], parts[p]).area(), w, p});
  }
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair& a, const Pair& b) { return a.shared > b.shared; });
  std::vector<bool> worker_done(n, false), part_done(n, false);
  for (const Pair& pair : pairs) {
    if (worker_done[pair.worker] || part_done[pair.part]) continue;
    worker_done[pair.worker] = part_done[pair.part] = true;
    regions_[pair.worker] = parts[pair.part];
  }
  region_ = region;
  config_.region = region;
  for (size_t w = 0; w < n; ++w) {
    Worker& worker = *workers_[w];
    if (!running_) {
      worker.sampler->set_region(regions_[w]);  // not started: no thread reads it
      continue;
    }
    std::lock_guard<std::mutex> lock(worker.region_mutex);
    worker.next_region = regions_[w];
    worker.region_changed.store(true, std::memory_order_release);
  }
}

void SamplerPool::start() {
  if (running_.exchange(true)) return;
  for (auto& w : workers_) w->thread = std::thread([this, p = w.get()] { run(p); });
}

void SamplerPool::stop() {
  running_ = false;
  for (auto& w : workers_) {
    if (w->thread.joinable()) w->thread.join();
  }
}

void SamplerPool::run(Worker* w) {
  if (options_.worker_nice > 0) {
    // This thread only (Linux: a thread's id names it to setpriority).
    const id_t self = id_t(::syscall(SYS_gettid));
    errno = 0;
    const int now = ::getpriority(PRIO_PROCESS, self);
    if (errno == 0 &&
        ::setpriority(PRIO_PROCESS, self, std::min(19, now + options_.worker_nice)) != 0) {
      spdlog::warn("sampler worker: cannot lower its priority: {}", std::strerror(errno));
    }
  }
  if (options_.worker_idle) {
    // This thread only: pid 0 names the calling thread.
    sched_param param{};
    if (::sched_setscheduler(0, SCHED_IDLE, &param) != 0) {
      spdlog::warn("sampler worker: cannot run under SCHED_IDLE: {}", std::strerror(errno));
    }
  }
  using Steady = std::chrono::steady_clock;
  Sampler& s = *w->sampler;
  // The fill's samples count against the cap like any others: the loop below waits them off.
  const double cap = options_.max_samples_per_second / double(workers_.size());
  // A worker that fell behind its capped schedule (a busy machine) may catch up by at most this
  // much: more would be a burst of samples when the machine frees up.
  const auto max_behind = std::chrono::duration_cast<Steady::duration>(
      std::chrono::duration<double>(kMaxCatchUpSeconds));
  auto start = Steady::now();
  const uint64_t start_samples = s.counters().samples;
  s.fill();
  int since_copy = 0;
  while (running_.load(std::memory_order_relaxed)) {
    if (w->region_changed.load(std::memory_order_acquire)) {
      std::optional<PixelRect> next;
      {
        std::lock_guard<std::mutex> lock(w->region_mutex);
        next.swap(w->next_region);
        w->region_changed.store(false, std::memory_order_relaxed);
      }
      if (next) s.set_region(*next);
    }
    s.step();
    if (cap > 0.0) {
      // Sleep until the samples so far are due at the capped rate.
      const double due = double(s.counters().samples - start_samples) / cap;
      const auto wake =
          start + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(due));
      const auto now = Steady::now();
      if (wake > now) {
        std::this_thread::sleep_until(wake);
      } else if (now - wake > max_behind) {
        start += (now - wake) - max_behind;
      }
    }
    if (++since_copy >= 64) {
      since_copy = 0;
      std::lock_guard<std::mutex> lock(w->counters_mutex);
      w->counters = s.counters();
    }
  }
  s.flush();
  std::lock_guard<std::mutex> lock(w->counters_mutex);
  w->counters = s.counters();
}

SamplerCounters SamplerPool::counters() const {
  SamplerCounters sum;
  for (const auto& w : workers_) {
    std::lock_guard<std::mutex> lock(w->counters_mutex);
    const SamplerCounters& c = w->counters;
    sum.samples += c.samples;
    sum.crosshairs += c.crosshairs;
    sum.reprojections += c.reprojections;
    sum.reprojections_dropped += c.reprojections_dropped;
    sum.occlusion_rays += c.occlusion_rays;
    sum.occlusion_hits += c.occlusion_hits;
    sum.splits += c.splits;
    sum.merges += c.merges;
    sum.sanitized += c.sanitized;
    sum.shadow_rays += c.shadow_rays;
    sum.snapshots += c.snapshots;
    sum.batches += c.batches;
  }
  return sum;
}

}  // namespace afr
