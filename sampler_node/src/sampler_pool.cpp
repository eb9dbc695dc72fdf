#include <afr/sampler/sampler_pool.h>

#include <afr/common/error.h>
#include <afr/common/region_split.h>

#include <fmt/format.h>

#include <chrono>
#include <mutex>

namespace afr {

namespace {

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
  regions_ = split_region(owned, std::vector<double>(size_t(options.threads), 1.0));
  for (int t = 0; t < options.threads; ++t) {
    auto w = std::make_unique<Worker>();
    SamplerConfig c = config_;
    c.region = regions_[t];
    c.seed = config_.seed + uint64_t(t) * 0x9e3779b97f4a7c15ULL;
    w->tracer = std::make_unique<Tracer>(scene_);
    w->clock = std::make_unique<SharedClock>(clock_);
    w->sampler = std::make_unique<Sampler>(scene_, *w->tracer, *w->clock, c, sink_);
    workers_.push_back(std::move(w));
  }
}

SamplerPool::~SamplerPool() { stop(); }

void SamplerPool::set_camera_source(const CameraSource* source) {
  for (auto& w : workers_) w->sampler->set_camera_source(source);
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
  Sampler& s = *w->sampler;
  // The fill's samples count against the cap like any others: the loop below waits them off.
  const double cap = options_.max_samples_per_second / double(workers_.size());
  const auto start = std::chrono::steady_clock::now();
  const uint64_t start_samples = s.counters().samples;
  s.fill();
  int since_copy = 0;
  while (running_.load(std::memory_order_relaxed)) {
    s.step();
    if (cap > 0.0) {
      // Sleep until the samples so far are due at the capped rate.
      const double due = double(s.counters().samples - start_samples) / cap;
      const auto wake = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                    std::chrono::duration<double>(due));
      if (wake > std::chrono::steady_clock::now()) std::this_thread::sleep_until(wake);
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
    sum.snapshots += c.snapshots;
    sum.batches += c.batches;
  }
  return sum;
}

}  // namespace afr
