// The framed baselines: double buffering (a frame shown at t_j was traced with the input of an
// earlier time), the frame schedule, the framed resolution and the upsampling.
#include <afr/eval/framed.h>
#include <afr/eval/run.h>

#include "eval_test_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace afr::eval {
namespace {

using testing::reference_frame;

TEST(FrameScheduleTest, ShowsTheNewestFrameDoneByTheDisplayTime) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (double period : {1.0 / 60.0, 0.16384, 0.655}) {
    const FrameSchedule s{0.25, period};
    for (int i = 0; i < 1000; ++i) {
      const double t = u(rng);
      const int64_t k = s.frame_shown_at(t);
      // Frame k is done (its successor has started) and frame k + 1 is not.
      EXPECT_LE(s.input_time(k + 1), t + 1e-9 * period);
      EXPECT_GT(s.input_time(k + 2), t);
    }
  }
  // 60 Hz frames aligned with the display: the frame shown at t_j took the input of t_(j-1),
  // also where floating point puts t_j a hair before the completion.
  const FrameSchedule s60{1.0, 1.0 / 60.0};
  for (int j = 0; j < 600; ++j) EXPECT_EQ(s60.frame_shown_at(1.0 + j / 60.0), j - 1) << j;
}

TEST(FramedTest, FrameShownAtTjWasTracedWithTheInputOfTjMinus1) {
  // 8 m/s at 3 m: about 1.2 pixels per frame, so consecutive frames differ.
  const Scene scene = testing::sliding_quad_scene(8.0);
  Tracer tracer(scene);
  RunSettings s;
  s.width = 48;
  s.height = 32;
  s.first_time = 0.2;
  s.frames = 12;
  s.threads = 2;
  for (Method method : {Method::kFullRes60, Method::kFramed60}) {
    s.method = method;
    s.rate = 60.0 * s.width * s.height;  // framed 60 Hz at full resolution: no upsampling
    std::vector<Image> shown;
    const RunStats stats =
        run_method(scene, tracer, s,
                   [&](int, const Image& image, const FrameInput&) { shown.push_back(image); });
    EXPECT_EQ(stats.frame_width, s.width);
    EXPECT_EQ(stats.frames_traced, uint64_t(s.frames));
    EXPECT_EQ(stats.primary_rays, uint64_t(s.frames) * s.width * s.height);
    ASSERT_EQ(shown.size(), size_t(s.frames));
    for (int j = 0; j < s.frames; ++j) {
      const double t = frame_time(s, j);
      const Image previous = reference_frame(tracer, t - 1.0 / 60.0, s.width, s.height);
      const Image current = reference_frame(tracer, t, s.width, s.height);
      EXPECT_EQ(shown[size_t(j)].pixels, previous.pixels) << method_name(method) << " frame " << j;
      EXPECT_NE(shown[size_t(j)].pixels, current.pixels) << method_name(method) << " frame " << j;
    }
  }
}

TEST(FrameScheduleTest, ShowsNoFrameWhoseInputIsNewerThanTheLatencyAllows) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (double period : {1.0 / 60.0, 0.16384}) {
    for (double latency : {0.0, 0.5 / 60.0, 1.0 / 60.0, 2.5 / 60.0, 0.4}) {
      const FrameSchedule s{0.25, period, latency};
      for (int i = 0; i < 1000; ++i) {
        const double t = u(rng);
        const int64_t k = s.frame_shown_at(t);
        const double slack = 1e-9 * period;
        // Done, and old enough ...
        EXPECT_LE(s.input_time(k + 1), t + slack);
        EXPECT_LE(s.input_time(k), t - latency + slack);
        // ... and the newest frame that is both.
        EXPECT_TRUE(s.input_time(k + 2) > t || s.input_time(k + 1) > t - latency)
            << "period " << period << " latency " << latency << " t " << t;
      }
    }
  }
}

TEST(FramedTest, FrameShownAtTjWasTracedWithTheInputOfTjMinus2AtALatencyOfTwoRefreshes) {
  const Scene scene = testing::sliding_quad_scene(8.0);
  Tracer tracer(scene);
  RunSettings s;
  s.width = 48;
  s.height = 32;
  s.first_time = 0.2;
  s.frames = 8;
  s.threads = 2;
  s.latency = 2.0 / 60.0;
  for (Method method : {Method::kFullRes60, Method::kFramed60}) {
    s.method = method;
    s.rate = 60.0 * s.width * s.height;
    std::vector<Image> shown;
    run_method(scene, tracer, s,
               [&](int, const Image& image, const FrameInput&) { shown.push_back(image); });
    ASSERT_EQ(shown.size(), size_t(s.frames));
    for (int j = 0; j < s.frames; ++j) {
      const double t = frame_time(s, j);
      const Image two_old = reference_frame(tracer, t - 2.0 / 60.0, s.width, s.height);
      const Image one_old = reference_frame(tracer, t - 1.0 / 60.0, s.width, s.height);
      EXPECT_EQ(shown[size_t(j)].pixels, two_old.pixels) << method_name(method) << " frame " << j;
      EXPECT_NE(shown[size_t(j)].pixels, one_old.pixels) << method_name(method) << " frame " << j;
    }
  }
}

TEST(FramedTest, FullResolutionFramesAreAsOldAsTheRateMakesThem) {
  const Scene scene = testing::sliding_quad_scene(1.0);
  Tracer tracer(scene);
  RunSettings s;
  s.method = Method::kFramedFullRes;
  s.width = 40;
  s.height = 30;
  s.rate = 10.0 * s.width * s.height;  // 10 full frames per second: period 0.1 s
  s.first_time = 1.0;
  s.frames = 30;
  std::vector<Image> shown;
  const RunStats stats =
      run_method(scene, tracer, s,
                 [&](int, const Image& image, const FrameInput&) { shown.push_back(image); });
  EXPECT_NEAR(stats.frame_period, 0.1, 1e-12);
  // 30 display frames span 0.5 s: 5 or 6 frames shown.
  EXPECT_GE(stats.frames_traced, 5u);
  EXPECT_LE(stats.frames_traced, 6u);
  for (int j = 0; j < s.frames; ++j) {
    const double t = frame_time(s, j);
    // The newest frame done by t began at the largest 1 + 0.1 k with 1 + 0.1 (k + 1) <= t.
    const double input = 1.0 + 0.1 * (std::floor((t - 1.0) / 0.1 + 1e-9) - 1.0);
    EXPECT_EQ(shown[size_t(j)].pixels, reference_frame(tracer, input, s.width, s.height).pixels)
        << "frame " << j;
  }
}

TEST(FramedTest, ResolutionKeepsTheAspectAndTheBudget) {
  int w, h;
  framed_resolution(400000.0 / 60.0, 256, 256, &w, &h);
  EXPECT_EQ(w, 81);
  EXPECT_EQ(h, 81);
  framed_resolution(100000.0 / 60.0, 512, 256, &w, &h);
  EXPECT_LE(w * h, 1667);
  EXPECT_EQ(w, 2 * h);
  framed_resolution(1e12, 64, 48, &w, &h);
  EXPECT_EQ(w, 64);
  EXPECT_EQ(h, 48);
  framed_resolution(0.5, 64, 48, &w, &h);
  EXPECT_EQ(w * h, 1);
}

TEST(FramedTest, BilinearUpsamplingKeepsConstantsAndLinearRamps) {
  Image src(4, 3);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) src.at(x, y) = glm::vec3(float(x), float(y), 0.5f);
  }
  const Image up = upsample_bilinear(src, 16, 12);
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) {
      // Away from the clamped border, a ramp in source pixels stays a ramp: value = source
      // coordinate of the output pixel's center.
      const float u = std::clamp((x + 0.5f) / 4.0f - 0.5f, 0.0f, 3.0f);
      const float v = std::clamp((y + 0.5f) / 4.0f - 0.5f, 0.0f, 2.0f);
      EXPECT_NEAR(up.at(x, y).r, u, 1e-5f);
      EXPECT_NEAR(up.at(x, y).g, v, 1e-5f);
      EXPECT_FLOAT_EQ(up.at(x, y).b, 0.5f);
    }
  }
}

}  // namespace
}  // namespace afr::eval
