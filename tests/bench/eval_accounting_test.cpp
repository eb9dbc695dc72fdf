// The evaluation's accounting (docs/evaluation.md, "What is compared"): one display rule for
// every method (the image shown at t_j uses no input newer than t_j - latency) and one ray
// budget (the sampler's occlusion rays are paid for like any other ray).
#include <afr/common/builtin_scene.h>
#include <afr/eval/ray_budget.h>
#include <afr/eval/run.h>

#include "eval_test_scenes.h"

#include <gtest/gtest.h>

#include <cmath>

namespace afr::eval {
namespace {

struct Shown {
  std::vector<Image> images;
  std::vector<FrameInput> inputs;
};

Shown run(const Scene& scene, Tracer& tracer, const RunSettings& s, RunStats* stats = nullptr) {
  Shown shown;
  const RunStats st =
      run_method(scene, tracer, s, [&](int j, const Image& image, const FrameInput& in) {
        EXPECT_EQ(size_t(j), shown.images.size());
        shown.images.push_back(image);
        shown.inputs.push_back(in);
      });
  if (stats) *stats = st;
  return shown;
}

TEST(BudgetClockTest, ChargesOcclusionRaysAtTheirCost) {
  for (double cost : {0.0, 0.5, 1.0, 2.0}) {
    BudgetClock clock(1000.0, 3.0, cost);
    clock.primary_rays_traced(100);
    clock.set_occlusion_rays(40);
    clock.primary_rays_traced(5);
    clock.set_occlusion_rays(50);  // a running total: 10 more
    EXPECT_EQ(clock.primary_rays(), 105u);
    EXPECT_EQ(clock.occlusion_rays(), 50u);
    EXPECT_DOUBLE_EQ(clock.charged_rays(), 105.0 + cost * 50.0);
    EXPECT_NEAR(clock.now(), 3.0 + (105.0 + cost * 50.0) / 1000.0, 1e-12) << cost;
  }
}

// With latency L, the image every method shows at t_j is made from a camera and scene time no
// newer than t_j - L and holds no sample newer than that; and it is the newest the method's
// pipeline allows (not older than it must be).
TEST(AccountingTest, EveryMethodsFrameAtTjUsesNoInputNewerThanTjMinusLatency) {
  const Scene scene = testing::sliding_quad_scene(2.0);
  Tracer tracer(scene);
  for (double latency_frames : {0.0, 1.0, 2.5}) {
    for (Method method : all_methods()) {
      RunSettings s;
      s.method = method;
      s.width = 32;
      s.height = 24;
      s.rate = method_uses_rate(method) ? 2e5 : 60.0 * s.width * s.height;
      s.first_time = 1.0;
      s.frames = 8;
      s.warmup = 0.2;
      s.threads = 1;
      s.latency = latency_frames / s.fps;
      RunStats stats;
      const Shown shown = run(scene, tracer, s, &stats);
      ASSERT_EQ(shown.inputs.size(), size_t(s.frames));
      for (int j = 0; j < s.frames; ++j) {
        const double newest_allowed = frame_time(s, j) - s.latency;
        const FrameInput& in = shown.inputs[size_t(j)];
        const std::string what = std::string(method_name(method)) + " latency " +
                                 std::to_string(latency_frames) + " frame " + std::to_string(j);
        EXPECT_LE(in.input_time, newest_allowed + 1e-12) << what;
        EXPECT_LE(in.newest_sample, newest_allowed + 1e-12) << what;
        EXPECT_LE(in.newest_sample, in.input_time + 1e-12) << what;
        if (method_is_frameless(method)) {
          // The display takes the camera of t_j - L exactly, and the samples traced until then
          // (the tracer's scene time follows the clock in 1 ms steps).
          EXPECT_DOUBLE_EQ(in.input_time, newest_allowed) << what;
          EXPECT_GT(in.newest_sample, newest_allowed - 2e-3) << what;
        } else {
          // A framed renderer shows its newest frame that is done and old enough: one frame
          // period (more for full-resolution frames at R) or L, whichever is longer.
          const double period = stats.frame_period;
          EXPECT_GT(in.input_time, frame_time(s, j) - std::max(period, s.latency) - period - 1e-9)
              << what;
          EXPECT_LE(in.input_time, frame_time(s, j) - period + 1e-9) << what;
        }
      }
    }
  }
}

// The display stage of the frameless methods sees the scene as it was L earlier: a run with
// latency L shows at t_j exactly what a zero-latency run that starts L earlier shows at
// t_j - L. Times are multiples of 1/16 s so that both runs compute the same numbers.
TEST(AccountingTest, FramelessImageWithLatencyIsTheZeroLatencyImageOfTjMinusLatency) {
  const Scene scene = testing::sliding_quad_scene(2.0);
  Tracer tracer(scene);
  for (Method method : {Method::kAdaptive, Method::kFrameless}) {
    RunSettings s;
    s.method = method;
    s.width = 32;
    s.height = 24;
    s.rate = 1e5;
    s.fps = 16.0;
    s.frames = 4;
    s.warmup = 0.25;
    s.threads = 1;
    s.first_time = 1.0;
    s.latency = 0.25;
    const Shown late = run(scene, tracer, s);
    s.first_time = 0.75;
    s.latency = 0.0;
    const Shown early = run(scene, tracer, s);
    s.first_time = 1.0;
    const Shown now = run(scene, tracer, s);
    for (int j = 0; j < s.frames; ++j) {
      EXPECT_EQ(late.images[size_t(j)].pixels, early.images[size_t(j)].pixels)
          << method_name(method) << " frame " << j;
      EXPECT_NE(late.images[size_t(j)].pixels, now.images[size_t(j)].pixels)
          << method_name(method) << " frame " << j << ": latency changed nothing";
    }
  }
}

// Every occlusion ray the adaptive sampler traces takes a ray from its budget: over the same
// virtual time, primary + occlusion rays with occlusion rays charged equal the primary rays
// of a run where they are free.
TEST(AccountingTest, OcclusionRaysAreChargedToTheRayBudget) {
  const Scene scene = make_builtin_scene();
  Tracer tracer(scene);
  RunSettings s;
  s.method = Method::kAdaptive;
  s.width = 48;
  s.height = 32;
  s.rate = 2e5;
  s.first_time = 2.0;
  s.frames = 12;
  s.warmup = 0.3;
  s.threads = 1;
  RunStats charged, free;
  s.occlusion_ray_cost = 1.0;
  run(scene, tracer, s, &charged);
  s.occlusion_ray_cost = 0.0;
  run(scene, tracer, s, &free);
  ASSERT_GT(charged.occlusion_rays, 1000u);
  EXPECT_DOUBLE_EQ(charged.charged_rays,
                   double(charged.primary_rays) + double(charged.occlusion_rays));
  EXPECT_DOUBLE_EQ(free.charged_rays, double(free.primary_rays));
  // Both runs sample the same virtual span (warm-up to the last frame's input time), so they
  // trace the same number of rays in all, up to one step's overshoot (a crosshair, r
  // reprojections and their replacements: well under 64 rays).
  const double paid = double(charged.primary_rays + charged.occlusion_rays);
  EXPECT_NEAR(paid, double(free.primary_rays), 64.0);
  EXPECT_LT(charged.primary_rays + charged.occlusion_rays / 2, free.primary_rays);
  // No method traces more than R allows.
  EXPECT_LE(paid, s.rate * charged.virtual_seconds + 1e-6);
  EXPECT_NEAR(charged.virtual_seconds, paid / s.rate, 1e-12);
}

TEST(AccountingTest, ScheduleSeedsSpreadOverTheFramePeriod) {
  EXPECT_EQ(schedule_phase(1), 0.0);
  std::vector<double> phases;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    const double p = schedule_phase(seed);
    EXPECT_GE(p, 0.0);
    EXPECT_LT(p, 1.0);
    for (double q : phases) EXPECT_GT(std::abs(p - q), 0.05) << seed;
    phases.push_back(p);
  }
}

}  // namespace
}  // namespace afr::eval
