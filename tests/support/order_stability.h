// Reconstruction stability: two CPU reconstructors of one scene that differ only in the
// arrival order of the samples (the second gets every pair of batches swapped, both hold the
// same samples at each image), or that get two sample streams of the sampler (seeds s and
// s + 1000). The real sampler traces under a virtual clock. A display's image is defined only
// up to such differences, so they must stay small and not grow image after image
// (docs/reconstruction.md, "Coverage map"). Used by the stability test
// (tests/service/reconstruction_stability_test.cpp) at fixed settings and by
// afr-bench-stability (bench/stability_bench.cpp), which takes the settings as flags.
// Header-only, like wall_seam.h, so that each builds without the other.
#pragma once

#include <afr/common/clock.h>
#include <afr/common/image.h>
#include <afr/common/scene.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/tracer.h>

#include <cmath>
#include <functional>
#include <memory>

namespace afr::testing {

struct StabilitySettings {
  ImageExtent size{256, 256};
  double rate = 400000.0;  // primary rays per second (virtual clock)
  int images = 600;
  double fps = 60.0;
  uint64_t seed = 1;
  bool still = false;          // the scene frozen past the end of its animation
  bool compare_seeds = false;  // two sample streams instead of two arrival orders
};

namespace stability_detail {

// Feeds `a` every batch as it comes and `b` the same batches with each pair swapped;
// release() hands `b` a batch still held back.
class OrderSink final : public SampleSink {
 public:
  OrderSink(Reconstructor& a, Reconstructor* b) : a_(a), b_(b) {}
  void on_batch(SampleBatch&& batch) override {
    a_.add_batch(batch);
    if (b_ == nullptr) return;
    if (held_.samples.empty()) {
      held_ = std::move(batch);
    } else {
      b_->add_batch(batch);
      release();
    }
  }
  void on_tiling(TilingSnapshot&& snapshot) override {
    a_.set_tiling(snapshot);
    if (b_ != nullptr) b_->set_tiling(snapshot);
  }
  void release() {
    if (b_ == nullptr || held_.samples.empty()) return;
    b_->add_batch(held_);
    held_.samples.clear();
  }

 private:
  Reconstructor& a_;
  Reconstructor* b_;
  SampleBatch held_;
};

// A sampler under its own virtual clock feeding one reconstructor, or two (`twin`).
struct Pipeline {
  Pipeline(const Scene& scene, const StabilitySettings& s, uint64_t seed, double start, bool twin)
      : tracer(scene), clock(s.rate, start) {
    ReconstructorConfig rc;
    rc.image = s.size;
    rc.threads = 1;
    a = std::make_unique<CpuReconstructor>(rc);
    if (twin) b = std::make_unique<CpuReconstructor>(rc);
    sink = std::make_unique<OrderSink>(*a, b.get());
    SamplerConfig sc;
    sc.image = s.size;
    sc.seed = seed;
    sc.loop_animation = !s.still;
    sampler = std::make_unique<Sampler>(scene, tracer, clock, sc, *sink);
    sampler->fill();
  }
  void run_until(double t) {
    while (clock.now() < t) sampler->step();
    sampler->flush();
    sink->release();
  }
  Tracer tracer;
  VirtualClock clock;
  std::unique_ptr<CpuReconstructor> a, b;
  std::unique_ptr<OrderSink> sink;
  std::unique_ptr<Sampler> sampler;
};

}  // namespace stability_detail

// The scene time of display time t (looping, or frozen for a still scene).
inline double stability_scene_time(const Scene& scene, const StabilitySettings& s, double t) {
  return s.still || scene.duration() <= 0.0 ? t : std::fmod(t, scene.duration());
}

// Runs s.images images at s.fps and calls `each(image, display time, first, second)` after
// every one (image counts from 1).
inline void run_stability(
    const Scene& scene, const StabilitySettings& s,
    const std::function<void(int, double, const Image&, const Image&)>& each) {
  using stability_detail::Pipeline;
  // A still scene: the clock starts past the animation's end, where every channel is clamped.
  const double start = s.still ? scene.duration() + 1.0 : 0.0;
  Pipeline one(scene, s, s.seed, start, !s.compare_seeds);
  std::unique_ptr<Pipeline> other;
  if (s.compare_seeds) other = std::make_unique<Pipeline>(scene, s, s.seed + 1000, start, false);
  Reconstructor& second = s.compare_seeds ? *other->a : *one.b;
  Image ia, ib;
  for (int j = 1; j <= s.images; ++j) {
    const double t = start + double(j) / s.fps;
    one.run_until(t);
    if (other) other->run_until(t);
    const Camera camera = scene.camera_at(scene.evaluate(stability_scene_time(scene, s, t)));
    one.a->reconstruct(camera, t, s.size.width, s.size.height, &ia);
    second.reconstruct(camera, t, s.size.width, s.size.height, &ib);
    each(j, t, ia, ib);
  }
}

}  // namespace afr::testing
