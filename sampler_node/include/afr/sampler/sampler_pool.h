// Runs several samplers on worker threads for live use: the owned region is cut into one
// sub-region per thread (split_region, the same mechanism the service uses across nodes) and
// each thread runs its own Sampler with its own Tracer on a shared wall clock. The first
// thread's tracer builds the scene's BVHs; the others share what no time changes
// (Tracer::ShareGeometry), so a pool's memory and build time do not grow with its threads.
//
// Order of calls: construct, start(), then stop() (or destroy); set_region() at any time in
// between, from the thread that calls the others. The sink is called from the worker threads,
// so it must be thread-safe.
#pragma once

#include <afr/common/clock.h>
#include <afr/common/samples.h>
#include <afr/common/scene.h>
#include <afr/sampler/sampler.h>

#include <atomic>
#include <memory>
#include <thread>
#include <vector>

namespace afr {

struct SamplerPoolOptions {
  int threads = 1;
  // Samples per second over all threads; 0 = as fast as the machine allows.
  double max_samples_per_second = 0.0;
  // Added to the worker threads' nice value (0-19; Linux keeps one per thread): tracing yields
  // to a display sharing the cores while the node's control thread, and its heartbeats, keep
  // the process's priority.
  int worker_nice = 0;
  // The worker threads run under SCHED_IDLE (Linux): only when no other thread wants the core.
  // A display on the same cores then never waits for them (on Linux 6.x a waking thread does
  // not always preempt a niced one at once), but the samplers trace fewer and older samples,
  // and the live error was higher for it (docs/service.md, "What each node does").
  bool worker_idle = false;
  // A tracer of the pool's scene whose build the pool's tracers share (Tracer::ShareGeometry),
  // kept by the caller from pool to pool (a sampler node's new session or region on the same
  // scene starts without building the scene again); null: the pool builds it.
  const Tracer* geometry = nullptr;
  // The options of the tracers the pool builds; with `geometry`, that tracer's apply.
  TracerOptions tracer;
};

class SamplerPool {
 public:
  SamplerPool(const Scene& scene, const SamplerConfig& config, const SamplerPoolOptions& options,
              const Clock& clock, SampleSink& sink);
  ~SamplerPool();
  SamplerPool(const SamplerPool&) = delete;
  SamplerPool& operator=(const SamplerPool&) = delete;

  // Every worker takes its camera from `source` (see Sampler::set_camera_source). Call before
  // start(); the source must outlive the pool.
  void set_camera_source(const CameraSource* source);
  void start();
  void stop();
  // Counters summed over the threads (read while running: approximate, never torn per field).
  SamplerCounters counters() const;
  // Moves the pool to another region of the same image (a recut) without stopping it: the
  // region is cut into sub-regions as at construction and each worker takes the one it shares
  // the most pixels with, where its Sampler::set_region keeps its crosshairs. Each worker
  // switches at its next step; the fill of what it gains goes at the pool's capped rate.
  // Throws afr::Error when the region is outside the image or has fewer pixels than threads.
  void set_region(const PixelRect& region);
  const PixelRect& region() const { return region_; }
  // Worker t's sub-region (after set_region, the one it was given, whether or not it has
  // switched yet).
  const std::vector<PixelRect>& regions() const { return regions_; }

 private:
  struct Worker;
  void run(Worker* w);

  const Scene& scene_;
  SamplerConfig config_;
  SamplerPoolOptions options_;
  const Clock& clock_;
  SampleSink& sink_;
  PixelRect region_;
  std::vector<PixelRect> regions_;
  std::vector<std::unique_ptr<Worker>> workers_;
  std::atomic<bool> running_{false};
};

}  // namespace afr
