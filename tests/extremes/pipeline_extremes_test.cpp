// Numerical extremes of the whole path a sample takes: sampler, wire encoding and decoding,
// the display's store, tile field, filter and CPU reconstruction, under a virtual clock.
// Absolute times near 1e6 s and 1e9 s, 1 and 1e8 samples per second, black and one-colored
// scenes, a camera inside geometry, a near plane of 1e-6, scene scales of 1e6 and 1e-6,
// non-finite radiance at the display, a 32768-pixel image, one-pixel tiles and the filter's
// clamps.
#include <afr/display/cpu_reconstructor.h>
#include <afr/display/tile_field.h>

#include <afr/common/error.h>
#include <afr/common/image.h>
#include <afr/common/random.h>
#include <afr/protocol/codec.h>
#include <afr/protocol/packing.h>
#include <afr/sampler/sampler.h>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "extremes/extremes_support.h"
#include "support/test_scenes.h"

namespace afr {
namespace {

using extremes::finite3;
using extremes::sample_is_sane;
using extremes::snapshot_is_sane;
using extremes::stats_match_buffer;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// What the network does with the sampler's output: encode, decode, hand to the reconstructor.
// Also checks every sample and snapshot on the way, and counts what the encoder refused.
struct WireSink : SampleSink {
  int width, height;
  Reconstructor* rec;
  uint64_t samples = 0, bad = 0, refused = 0, snapshots = 0;
  double min_time = INFINITY, max_time = -INFINITY;
  std::string first_problem;
  std::vector<uint8_t> bytes;
  SampleBatch batch;
  TilingSnapshot snapshot;
  // With `keep`, every decoded batch, for replaying them into another reconstructor.
  bool keep = false;
  std::vector<SampleBatch> kept;

  WireSink(int w, int h, Reconstructor* r) : width(w), height(h), rec(r) {}
  void note(const std::string& problem) {
    if (first_problem.empty()) first_problem = problem;
  }
  void on_batch(SampleBatch&& b) override {
    for (const Sample& s : b.samples) {
      ++samples;
      min_time = std::min(min_time, s.time);
      max_time = std::max(max_time, s.time);
      if (const ::testing::AssertionResult r = sample_is_sane(s, width, height); !r) {
        ++bad;
        note(r.message());
      }
    }
    const ImageExtent bounds{width, height};
    if (const protocol::Status st = protocol::encode(b, &bytes, bounds); !st) {
      ++refused;
      note(st.message());
      return;
    }
    if (const protocol::Status st = protocol::decode(bytes, &batch, bounds); !st) {
      ++refused;
      note(st.message());
      return;
    }
    rec->add_batch(batch);
    if (keep) kept.push_back(batch);
  }
  void on_tiling(TilingSnapshot&& s) override {
    ++snapshots;
    if (const ::testing::AssertionResult r = snapshot_is_sane(s); !r) {
      ++bad;
      note(r.message());
    }
    const ImageExtent bounds{width, height};
    if (const protocol::Status st = protocol::encode(s, &bytes, bounds); !st) {
      ++refused;
      note(st.message());
      return;
    }
    if (const protocol::Status st = protocol::decode(bytes, &snapshot, bounds); !st) {
      ++refused;
      note(st.message());
      return;
    }
    rec->set_tiling(snapshot);
  }
};

ReconstructorConfig rec_config(int w, int h) {
  ReconstructorConfig c;
  c.image.width = w;
  c.image.height = h;
  c.threads = 2;
  return c;
}

// A sampler under a virtual clock feeding a CPU reconstructor through the wire format.
struct Pipeline {
  const Scene& scene;
  Tracer tracer;
  VirtualClock clock;
  CpuReconstructor rec;
  WireSink sink;
  Sampler sampler;

  Pipeline(const Scene& s, const SamplerConfig& cfg, double rate, double start = 0.0)
      : scene(s),
        tracer(s),
        clock(rate, start),
        rec(rec_config(cfg.image.width, cfg.image.height)),
        sink(cfg.image.width, cfg.image.height, &rec),
        sampler(s, tracer, clock, cfg, sink) {
    sampler.fill();
  }
  void run_until(double t) {
    while (clock.now() < t) sampler.step();
    sampler.flush();
  }
  void run_steps(int n) {
    for (int k = 0; k < n; ++k) sampler.step();
    sampler.flush();
  }
  // The scene's camera at display time t (animations loop, as the sampler plays them).
  Camera camera_at(double t) const {
    const double d = scene.duration();
    return scene.camera_at(scene.evaluate(d > 0.0 ? std::fmod(t, d) : t));
  }
  Image reconstruct() {
    const int w = sampler.config().image.width, h = sampler.config().image.height;
    return rec.reconstruct(camera_at(clock.now()), clock.now(), w, h);
  }
  // Everything on the way was finite and accepted, the statistics are exact (unless told
  // not to check them), and the last image is finite without the reconstructor's final guard
  // having had to act.
  void expect_clean(const Image& image, bool exact_stats = true) {
    EXPECT_GT(sink.samples, 0u);
    EXPECT_EQ(sink.bad, 0u) << sink.first_problem;
    EXPECT_EQ(sink.refused, 0u) << sink.first_problem;
    if (exact_stats) {
      EXPECT_TRUE(stats_match_buffer(sampler, clock.now()));
    }
    EXPECT_EQ(rec.frame_stats().nonfinite_pixels, 0u);
    EXPECT_EQ(rec.ingest_stats().rejected(), 0u);
    for (const glm::vec3& c : image.pixels) ASSERT_TRUE(finite3(c));
    std::vector<float> weights;
    rec.read_weights(&weights);
    for (float w : weights) ASSERT_TRUE(std::isfinite(w) && w >= 0.0f);
  }
};

SamplerConfig sampler_config(int w, int h, uint64_t seed = 3) {
  SamplerConfig c;
  c.image.width = w;
  c.image.height = h;
  c.seed = seed;
  return c;
}

// The exact image of a scene at scene time t: 4 x 4 rays per pixel through the tracer.
Image exact_image(const Scene& scene, double t, int w, int h) {
  Tracer tracer(scene);
  tracer.set_time(t);
  const Camera cam = tracer.camera();
  TraceStats stats;
  Image image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      glm::vec3 sum(0.0f);
      for (int j = 0; j < 4; ++j) {
        for (int i = 0; i < 4; ++i) {
          sum += tracer.trace(cam.ray(x + (i + 0.5) / 4, y + (j + 0.5) / 4, w, h), &stats).color;
        }
      }
      image.at(x, y) = sum / 16.0f;
    }
  }
  return image;
}

// ---------------------------------------------------------------------------------------------
// Time

TEST(ExtremesTest, AbsoluteTimesNear1e6And1e9FilterLikeTheSessionStart) {
  // The moving scene rendered for 0.6 s from display times 0, 1e6 and 1e9 (multiples of the
  // animation's 2 s loop, so the scene does the same). The sampler: sample times exact
  // doubles in the run's time span, statistics exact, the image as good as any run's. The
  // display: the session-start run's samples and tiling, moved to 1e6 s and 1e9 s, give the
  // same image to 1e-4 (a time kept in float anywhere would be off by up to 64 s at 1e9).
  const Scene scene = testing::moving_scene();
  constexpr int kSide = 48;
  constexpr double kSpan = 0.6;
  const Image truth = exact_image(scene, kSpan, kSide, kSide);
  Pipeline first(scene, sampler_config(kSide, kSide), 2e5, 0.0);
  first.sink.keep = true;
  first.run_until(kSpan);
  const double end = first.clock.now();
  const Image at_zero = first.reconstruct();
  first.expect_clean(at_zero);
  EXPECT_LT(rms_error_255(at_zero, truth), 20.0);  // a black image scores ~125
  for (double start : {1e6, 1e9}) {
    SCOPED_TRACE(start);
    Pipeline p(scene, sampler_config(kSide, kSide), 2e5, start);
    p.run_until(start + kSpan);
    EXPECT_GE(p.sink.min_time, start);
    EXPECT_LE(p.sink.max_time, p.clock.now());
    EXPECT_GT(p.sink.snapshots, 30u);
    const Image image = p.reconstruct();
    p.expect_clean(image);
    EXPECT_EQ(p.rec.frame_stats().future, 0u);
    EXPECT_LT(p.rec.frame_stats().depth, 1.0f);  // the store reaches back ~0.05 s, not 1e9
    EXPECT_LT(rms_error_255(image, truth), 20.0);

    CpuReconstructor replay(rec_config(kSide, kSide));
    for (SampleBatch b : first.sink.kept) {
      for (Sample& s : b.samples) s.time += start;
      replay.add_batch(b);
    }
    TilingSnapshot tiling = first.sink.snapshot;
    tiling.time += start;
    replay.set_tiling(tiling);
    const Image moved = replay.reconstruct(first.camera_at(end), start + end, kSide, kSide);
    EXPECT_EQ(replay.frame_stats().nonfinite_pixels, 0u);
    EXPECT_EQ(replay.frame_stats().future, 0u);
    for (size_t i = 0; i < moved.pixels.size(); ++i) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_NEAR(moved.pixels[i][c], at_zero.pixels[i][c], 1e-4f) << "pixel " << i;
      }
    }
  }
}

TEST(ExtremesTest, OneSamplePerSecondStaysFinite) {
  // Five hours at one primary ray per virtual second: every crosshair is seconds older than
  // the last, weights underflow at every step, snapshots come at every step with rates near
  // zero, and the display's measured rate is far below its clamp.
  const Scene scene = testing::moving_scene();
  Pipeline p(scene, sampler_config(32, 32), 1.0);
  p.run_until(5.0 * 3600.0);
  const Image image = p.reconstruct();
  p.expect_clean(image);  // with exact statistics, though a tile's crosshairs are seconds apart
  for (int t : p.sampler.tiling().tiles()) {
    const TileStats st = p.sampler.tile_stats(t);
    ASSERT_TRUE(std::isfinite(st.v) && st.v >= 0.0 && std::isfinite(st.G_t) &&
                std::isfinite(st.mean_age));
  }
  EXPECT_GT(p.sink.snapshots, 1000u);
  EXPECT_EQ(p.rec.frame_stats().empty_pixels, 0u);  // the oldest samples still show
  EXPECT_GE(p.sampler.target_tiles(), 1);
  EXPECT_LE(p.sampler.target_tiles(), p.sampler.config().max_tiles);
}

TEST(ExtremesTest, HundredMillionSamplesPerSecondStaysFinite) {
  // 1e8 rays per virtual second: consecutive samples are 10 ns apart, less than a temporal
  // gradient's guard and far less than the display's shortest temporal extent.
  const Scene scene = testing::moving_scene();
  SamplerConfig cfg = sampler_config(32, 32);
  cfg.refresh_interval = 1e-4;  // snapshots even in a millisecond
  Pipeline p(scene, cfg, 1e8, 0.3);
  p.run_steps(30000);
  EXPECT_LT(p.clock.now(), 0.31);
  EXPECT_GT(p.sink.snapshots, 10u);
  EXPECT_GT(p.sampler.sample_rate(), 1e7);
  p.reconstruct();  // the second image sizes its splats from the first one's coverage
  const Image image = p.reconstruct();
  p.expect_clean(image);
  EXPECT_EQ(p.rec.frame_stats().empty_pixels, 0u);
  // The scene hardly moves in 2 ms: the image is the scene at that time, within the noise of
  // the store's 4 samples per pixel under the narrowest filter (a black image scores ~125).
  EXPECT_LT(rms_error_255(image, exact_image(scene, p.clock.now(), 32, 32)), 40.0);
}

// ---------------------------------------------------------------------------------------------
// Scenes without any change

void expect_one_color_scene_is_exact(glm::vec3 color) {
  Scene scene = testing::camera_scene();
  testing::add_quad(&scene, color, {-10, -10}, {10, 10});
  scene.finalize();
  SamplerConfig cfg = sampler_config(32, 32);
  Pipeline p(scene, cfg, 1e5);
  p.run_steps(6000);
  const Image image = p.reconstruct();
  p.expect_clean(image);
  // Zero gradients and variance everywhere, in the sampler and in every snapshot it sent.
  for (int t : p.sampler.tiling().tiles()) {
    const TileStats st = p.sampler.tile_stats(t);
    EXPECT_EQ(st.v, 0.0);
    EXPECT_EQ(st.G_x, 0.0);
    EXPECT_EQ(st.G_y, 0.0);
    EXPECT_EQ(st.G_t, 0.0);
  }
  for (const TileInfo& t : p.sink.snapshot.tiles) {
    EXPECT_EQ(t.G_x, 0.0f);
    EXPECT_EQ(t.G_y, 0.0f);
    EXPECT_EQ(t.G_t, 0.0f);
    EXPECT_TRUE(std::isfinite(t.E) && std::isfinite(t.rate));
  }
  EXPECT_GT(p.sink.snapshots, 0u);
  // Gain control with nothing to go by keeps a count inside its bounds.
  EXPECT_GE(p.sampler.target_tiles(), cfg.min_tiles);
  EXPECT_LE(p.sampler.target_tiles(), cfg.max_tiles);
  // The image is the color, as the wire carries it, at every pixel.
  const protocol::Rgb wire =
      protocol::decode_rgb9e5(protocol::encode_rgb9e5(color.r, color.g, color.b));
  for (const glm::vec3& c : image.pixels) {
    ASSERT_NEAR(c.r, wire.r, 1e-6f * (1.0f + wire.r));
    ASSERT_NEAR(c.g, wire.g, 1e-6f * (1.0f + wire.g));
    ASSERT_NEAR(c.b, wire.b, 1e-6f * (1.0f + wire.b));
  }
  EXPECT_EQ(p.rec.frame_stats().empty_pixels, 0u);
}

TEST(ExtremesTest, AllBlackSceneHasZeroGradientsAndAFiniteImage) {
  expect_one_color_scene_is_exact(glm::vec3(0.0f));
}

TEST(ExtremesTest, SingleColorSceneHasZeroGradientsAndReconstructsExactly) {
  expect_one_color_scene_is_exact(glm::vec3(0.25f, 0.5f, 3.0f));
}

// ---------------------------------------------------------------------------------------------
// Cameras

TEST(ExtremesTest, CameraInsideAClosedBoxStaysFinite) {
  // The eye inside a closed box of six emissive faces (seen from their back sides, lit by a
  // light inside it), and a seventh quad edge-on through the eye itself.
  Scene scene = testing::camera_scene();
  const glm::vec3 front(0.9f, 0.6f, 0.3f);
  testing::add_quad(&scene, front, {-1, -1}, {1, 1}, -1.0f);
  testing::add_quad(&scene, glm::vec3(0.1f, 0.2f, 0.3f), {-1, -1}, {1, 1}, 1.0f);
  // Side faces: quads at z = -1 rotated into place by their nodes.
  const glm::vec3 side_colors[4] = {
      {0.5f, 0.0f, 0.0f}, {0.0f, 0.5f, 0.0f}, {0.0f, 0.0f, 0.5f}, {0.5f, 0.5f, 0.0f}};
  const glm::dquat turns[4] = {glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 1, 0)),
                               glm::angleAxis(glm::radians(-90.0), glm::dvec3(0, 1, 0)),
                               glm::angleAxis(glm::radians(90.0), glm::dvec3(1, 0, 0)),
                               glm::angleAxis(glm::radians(-90.0), glm::dvec3(1, 0, 0))};
  for (int k = 0; k < 4; ++k) {
    const int n = testing::add_quad(&scene, side_colors[k], {-1, -1}, {1, 1}, -1.0f);
    scene.nodes[n].rotation = turns[k];
  }
  const int through =
      testing::add_quad(&scene, glm::vec3(2.0f), {-0.5f, -0.5f}, {0.5f, 0.5f}, 0.0f);
  scene.nodes[through].rotation = glm::angleAxis(glm::radians(90.0), glm::dvec3(1, 0, 0));
  Light light;
  light.intensity = 3.0f;
  scene.lights.push_back(light);
  Node ln;
  ln.light = 0;
  ln.translation = glm::dvec3(0.2, 0.3, -0.1);
  scene.nodes.push_back(ln);
  scene.finalize();
  Pipeline p(scene, sampler_config(40, 40), 1e5);
  p.run_steps(6000);
  const Image image = p.reconstruct();
  p.expect_clean(image);
  EXPECT_EQ(p.rec.frame_stats().empty_pixels, 0u);
  // Away from the edge-on quad's row, the middle of the view is the front face.
  for (int y : {8, 12, 27, 31}) {
    for (int x = 14; x < 26; ++x) {
      const glm::vec3 c = image.at(x, y);
      EXPECT_NEAR(c.r, front.r, 0.01f) << x << "," << y;
      EXPECT_NEAR(c.b, front.b, 0.01f) << x << "," << y;
    }
  }
}

// A camera at z = 0 whose near plane is 1e-6, looking at an emissive square 2e-6 in front of
// it that fills the middle of the view, and a wall 1 unit away; the camera slides sideways
// by 1e-6 per second, so the near square moves across the view while the wall stays.
Scene near_plane_scene() {
  Scene s;
  s.source = "near";
  CameraModel lens;
  lens.yfov = glm::radians(60.0);
  lens.znear = 1e-6;
  s.cameras.push_back(lens);
  Node cam;
  cam.camera = 0;
  s.nodes.push_back(cam);
  testing::add_quad(&s, glm::vec3(0.3f), {-10, -10}, {10, 10}, -1.0f);
  testing::add_quad(&s, glm::vec3(1.0f, 0.5f, 0.25f), {-5e-7f, -5e-7f}, {5e-7f, 5e-7f}, -2e-6f);
  AnimationChannel ch;
  ch.node = 0;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 1.0, 2.0};
  ch.values = {{-1e-6, 0, 0, 0}, {1e-6, 0, 0, 0}, {-1e-6, 0, 0, 0}};
  s.channels.push_back(ch);
  s.finalize();
  return s;
}

TEST(ExtremesTest, NearPlaneOfOneMillionthReprojectsAndStaysFinite) {
  const Scene scene = near_plane_scene();
  Pipeline p(scene, sampler_config(48, 48), 2e5);
  p.run_until(0.8);
  const Image image = p.reconstruct();
  p.expect_clean(image);
  EXPECT_GT(p.sampler.counters().reprojections, 1000u);
  // Reprojection kept most samples in front of the near plane (the display's count of
  // samples it found behind the camera is small next to what it splatted).
  EXPECT_LT(p.rec.frame_stats().behind_camera, p.rec.frame_stats().splatted / 10);
  EXPECT_LT(rms_error_255(image, exact_image(scene, 0.8, 48, 48)), 25.0);
}

// ---------------------------------------------------------------------------------------------
// Scene scale

// Emissive quads at several depths and a square sliding in front of them, every length times
// `scale`, with the camera at the origin.
Scene scaled_scene(double scale) {
  Scene s = testing::camera_scene();
  s.cameras[0].znear = 0.01 * scale;
  const float k = float(scale);
  testing::add_quad(&s, glm::vec3(0.2f), glm::vec2(-10) * k, glm::vec2(10) * k, -3.0f * k);
  testing::add_quad(&s, glm::vec3(0.9f, 0.4f, 0.1f), glm::vec2(-10, -10) * k,
                    glm::vec2(0.0123f, 10) * k, -2.0f * k);
  const int square = testing::add_quad(&s, glm::vec3(0.1f, 0.6f, 1.0f), glm::vec2(-0.1f) * k,
                                       glm::vec2(0.1f) * k, -1.0f * k);
  AnimationChannel ch;
  ch.node = square;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 1.0, 2.0};
  ch.values = {{-0.4 * scale, 0, 0, 0}, {0.4 * scale, 0, 0, 0}, {-0.4 * scale, 0, 0, 0}};
  s.channels.push_back(ch);
  s.finalize();
  return s;
}

// Renders scaled_scene(scale) for 0.5 s; returns the image's error against the truth at unit
// scale and the sampler's occlusion hits. With `replay_scale`, also replays the run's samples
// with their world positions multiplied by it (and the camera's), and expects the image of
// the run itself.
double scaled_run(double scale, const Image& truth, uint64_t* occlusion_hits,
                  double replay_scale = 0.0) {
  const Scene scene = scaled_scene(scale);
  Pipeline p(scene, sampler_config(truth.width, truth.height), 2e5);
  p.sink.keep = replay_scale != 0.0;
  p.run_until(0.5);
  const Image image = p.reconstruct();
  p.expect_clean(image);
  *occlusion_hits = p.sampler.counters().occlusion_hits;
  if (replay_scale != 0.0) {
    CpuReconstructor replay(rec_config(truth.width, truth.height));
    for (SampleBatch b : p.sink.kept) {
      for (Sample& s : b.samples) {
        if (!s.miss) s.position *= float(replay_scale);
        s.velocity *= float(replay_scale);
      }
      replay.add_batch(b);
    }
    replay.set_tiling(p.sink.snapshot);
    Camera cam = p.camera_at(p.clock.now());
    cam.eye *= replay_scale;
    cam.znear *= replay_scale;
    const Image moved = replay.reconstruct(cam, p.clock.now(), truth.width, truth.height);
    EXPECT_EQ(replay.frame_stats().nonfinite_pixels, 0u);
    // Float positions a million times larger or smaller project to the same pixels but for
    // rounding: only pixels at edges may differ.
    int differ = 0;
    for (size_t i = 0; i < moved.pixels.size(); ++i) {
      differ += glm::length(moved.pixels[i] - image.pixels[i]) > 1e-3f;
    }
    EXPECT_LE(differ, int(moved.pixels.size()) / 50) << "replayed at " << replay_scale;
  }
  return rms_error_255(image, truth);
}

TEST(ExtremesTest, SceneScalesOfAMillionAndAMillionthStayFinite) {
  // The same scene in units a million times larger and smaller: every output of the sampler
  // and the display finite, and the image of the scene. The display alone reprojects a unit
  // run's samples scaled by 1e6 and 1e-6 into the same image.
  const Image truth = exact_image(scaled_scene(1.0), 0.5, 40, 40);
  uint64_t hits_at_one, hits_large, hits_small;
  EXPECT_LT(scaled_run(1.0, truth, &hits_at_one), 20.0);  // a black image scores ~100
  EXPECT_GT(hits_at_one, 50u);
  uint64_t unused;
  scaled_run(1.0, truth, &unused, 1e6);
  scaled_run(1.0, truth, &unused, 1e-6);
  EXPECT_LT(scaled_run(1e6, truth, &hits_large), 20.0);
  EXPECT_GT(hits_large, hits_at_one / 2);
  // At 1e-6 the occlusion rays find nothing without the sampler fix of README.md ("Pending"), and
  // the moving square leaves a ghost; the occlusion test below is disabled until then.
  EXPECT_LT(scaled_run(1e-6, truth, &hits_small), 25.0);
}

TEST(ExtremesTest, OcclusionRaysWorkAtAMillionthScale) {
  // The occlusion ray of a reprojection starts off the surface by a distance relative to the
  // way to the eye and to the point's coordinates: an absolute 1e-4 would start it past the
  // eye of a scene in micrometres, and it would never hit.
  const Image truth = exact_image(scaled_scene(1.0), 0.5, 40, 40);
  uint64_t hits_at_one, hits_small;
  scaled_run(1.0, truth, &hits_at_one);
  EXPECT_LT(scaled_run(1e-6, truth, &hits_small), 20.0);
  EXPECT_GT(hits_small, hits_at_one / 2);
}

TEST(ExtremesTest, DefaultCameraFramesTheSceneAtEveryScale) {
  // A scene without a camera gets one that sees all of it, whatever its unit: the geometry
  // projects inside the image, in front of the near plane, and fills a good part of it.
  for (double scale : {1e-6, 1.0, 1e6}) {
    Scene s;
    s.source = "no camera";
    const float k = float(scale);
    testing::add_quad(&s, glm::vec3(1.0f), glm::vec2(-1.0f, -0.5f) * k, glm::vec2(1.0f, 0.5f) * k,
                      -3.0f * k);
    s.finalize();
    const Camera cam = s.camera_at(s.evaluate(0.0));
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::vec3& v : s.meshes[0].primitives[0].positions) {
      glm::dvec2 xy;
      double depth;
      ASSERT_TRUE(cam.project(glm::dvec3(v), 100, 100, &xy, &depth)) << scale;
      EXPECT_GT(depth, 2.0 * cam.znear) << scale;
      EXPECT_GE(xy.x, 0.0);
      EXPECT_LE(xy.x, 100.0);
      lo = std::min(lo, xy.x);
      hi = std::max(hi, xy.x);
    }
    EXPECT_GT(hi - lo, 50.0) << "the scene at scale " << scale << " covers " << hi - lo << " px";
  }
}

// ---------------------------------------------------------------------------------------------
// Radiance

TEST(ExtremesTest, NanAndInfRadianceIsRejectedOrClampedAtTheDisplay) {
  // A batch from a broken sampler: NaN and infinite colors are rejected and counted, colors
  // beyond the half-float range and negative ones clamped and counted. The image is exactly
  // what the good samples alone (with the clamped colors) give.
  Pcg32 rng(9);
  SampleBatch mixed, clean;
  int nonfinite = 0, clamped = 0;
  const float bad_values[] = {kNaN, kInf, -kInf};
  for (int i = 0; i < 20000; ++i) {
    Sample s;
    s.x = 32.0f * rng.next_float();
    s.y = 32.0f * rng.next_float();
    s.time = 0.5 * rng.next_double();
    s.color = glm::vec3(rng.next_float(), rng.next_float(), rng.next_float());
    const uint32_t kind = rng.next_below(10);
    if (kind == 0) {
      s.color[int(rng.next_below(3))] = bad_values[rng.next_below(3)];
      ++nonfinite;
      mixed.samples.push_back(s);
      continue;
    }
    mixed.samples.push_back(s);
    if (kind == 1) {
      mixed.samples.back().color.g = 3e38f;
      s.color.g = kMaxColor;
      ++clamped;
    } else if (kind == 2) {
      mixed.samples.back().color.b = -1e30f;
      s.color.b = 0.0f;
      ++clamped;
    }
    clean.samples.push_back(s);
  }
  // A tiling whose tiles carry NaN, Inf and negative gradients and rates: zeroed, counted.
  TilingSnapshot tiling;
  tiling.region = PixelRect{0, 0, 32, 32};
  tiling.time = 0.4;
  for (int k = 0; k < 4; ++k) {
    TileInfo t;
    t.rect = PixelRect{8 * k, 0, 8 * k + 8, 32};
    t.G_x = k == 0 ? kNaN : 0.1f;
    t.G_y = k == 1 ? kInf : 0.1f;
    t.G_t = k == 2 ? -1.0f : 0.5f;
    t.rate = k == 3 ? kNaN : 100.0f;
    tiling.tiles.push_back(t);
  }
  TilingSnapshot clean_tiling = tiling;
  for (TileInfo& t : clean_tiling.tiles) {
    for (float* v : {&t.G_x, &t.G_y, &t.G_t, &t.rate}) {
      if (!std::isfinite(*v) || *v < 0.0f) *v = 0.0f;
    }
  }
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  CpuReconstructor a(rec_config(32, 32)), b(rec_config(32, 32));
  a.add_batch(mixed);
  a.set_tiling(tiling);
  b.add_batch(clean);
  b.set_tiling(clean_tiling);
  const Image ia = a.reconstruct(cam, 0.5, 32, 32);
  const Image ib = b.reconstruct(cam, 0.5, 32, 32);
  EXPECT_EQ(a.ingest_stats().bad_color, uint64_t(nonfinite));
  EXPECT_EQ(a.ingest_stats().clamped_color, uint64_t(clamped));
  EXPECT_EQ(a.ingest_stats().accepted, clean.samples.size());
  EXPECT_EQ(a.tiling_stats().bad_values, 4u);
  EXPECT_EQ(a.frame_stats().nonfinite_pixels, 0u);
  for (size_t i = 0; i < ia.pixels.size(); ++i) {
    ASSERT_TRUE(finite3(ia.pixels[i]));
    ASSERT_EQ(ia.pixels[i], ib.pixels[i]) << i;
  }
  // The clamped colors are bright, so the sums are large, but nothing overflowed.
  float brightest = 0.0f;
  for (const glm::vec3& c : ia.pixels) brightest = std::max(brightest, c.g);
  EXPECT_GT(brightest, 100.0f);
}

// ---------------------------------------------------------------------------------------------
// Image size

long peak_rss_kib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

TEST(ExtremesTest, DisplayOf32768ImageIndexesWithoutOverflowAndAllocatesForItsOutput) {
  // A 32768 x 32768 sampling image, N = 2^18 samples, reconstructed at 512 x 512 and at
  // 2048 x 1024. Samples reach the far corner (the last float below 32768); tiles cover it.
  // Nothing may be allocated per sampling-image pixel (that would be >= 4 GiB).
  constexpr int kSide = 32768;
  ReconstructorConfig cfg = rec_config(kSide, kSide);
  EXPECT_THROW(CpuReconstructor{cfg}, Error);  // the default N = 4 x pixels is over the limit
  cfg.capacity = size_t(1) << 18;
  // Splats wide enough (16 px before the downscale) that the far corner's samples reach its
  // output pixel whatever the default largest extent.
  cfg.filter.max_spatial_extent = 16.0f;
  const long rss_before = peak_rss_kib();
  CpuReconstructor rec(cfg);
  Pcg32 rng(21);
  const glm::vec3 color(0.25f, 0.5f, 0.75f);
  const float last = std::nextafter(float(kSide), 0.0f);
  SampleBatch batch;
  for (int i = 0; i < 200000; ++i) {
    Sample s;
    s.x = std::min(float(kSide) * rng.next_float(), last);
    s.y = std::min(float(kSide) * rng.next_float(), last);
    s.time = rng.next_double();
    s.color = color;
    batch.samples.push_back(s);
  }
  for (int i = 0; i < 100; ++i) {  // the four corners
    Sample s;
    s.x = (i & 1) ? last : 0.0f;
    s.y = (i & 2) ? last : 0.0f;
    s.time = 1.0;
    s.color = color;
    batch.samples.push_back(s);
  }
  // Through the wire, as a sampler of the whole image would send it.
  std::vector<uint8_t> bytes;
  SampleBatch decoded;
  for (size_t first = 0; first < batch.samples.size(); first += protocol::kMaxSamplesPerBatch) {
    SampleBatch part;
    part.samples.assign(
        batch.samples.begin() + ptrdiff_t(first),
        batch.samples.begin() +
            ptrdiff_t(std::min(batch.samples.size(), first + protocol::kMaxSamplesPerBatch)));
    const protocol::Status enc = protocol::encode(part, &bytes, {kSide, kSide});
    ASSERT_TRUE(enc.ok()) << enc.message();
    const protocol::Status dec = protocol::decode(bytes, &decoded, {kSide, kSide});
    ASSERT_TRUE(dec.ok()) << dec.message();
    for (const Sample& s : decoded.samples) {
      ASSERT_LT(s.x, float(kSide));
      ASSERT_LT(s.y, float(kSide));
    }
    rec.add_batch(decoded);
  }
  // Tiles of the whole image, small ones at the far corner, one of a single pixel.
  TilingSnapshot tiling;
  tiling.region = PixelRect{0, 0, kSide, kSide};
  tiling.time = 1.0;
  const auto add_tile = [&](PixelRect r, float g) {
    TileInfo t;
    t.rect = r;
    t.G_x = t.G_y = g;
    t.G_t = 0.1f;
    t.rate = 1e-3f;
    tiling.tiles.push_back(t);
  };
  add_tile({0, 0, kSide, kSide - 64}, 0.01f);
  add_tile({0, kSide - 64, kSide - 64, kSide}, 0.02f);
  add_tile({kSide - 64, kSide - 64, kSide - 1, kSide}, 0.5f);
  add_tile({kSide - 1, kSide - 64, kSide, kSide - 1}, 0.7f);
  add_tile({kSide - 1, kSide - 1, kSide, kSide}, 1.0f);
  rec.set_tiling(tiling);
  EXPECT_EQ(rec.tiling_stats().dropped_tiles, 0u);
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  for (const auto& [w, h] : {std::pair{512, 512}, std::pair{2048, 1024}}) {
    const Image image = rec.reconstruct(cam, 1.0, w, h);
    EXPECT_EQ(rec.frame_stats().stored, std::min(cfg.capacity, batch.samples.size()));
    EXPECT_EQ(rec.frame_stats().nonfinite_pixels, 0u);
    EXPECT_EQ(rec.frame_stats().off_screen, 0u);
    for (const glm::vec3& c : image.pixels) {
      ASSERT_NEAR(c.r, color.r, 1e-5f);
      ASSERT_NEAR(c.b, color.b, 1e-5f);
    }
    std::vector<float> weights;
    rec.read_weights(&weights);
    EXPECT_EQ(weights.size(), size_t(w) * size_t(h));
    // The far corner's output pixel got samples from the corner (weight > 0).
    EXPECT_GT(weights.back(), 0.0f);
  }
  EXPECT_EQ(rec.capacity(), cfg.capacity);
  // The big tiles enter on the rate lattice of the output's scale (tile_field.h): at 2048 x
  // 1024, 1024 px cells (the smaller scale, 1/32), so 32 x 32 pieces of the first tile and 32
  // of the second, not a million 32 px pieces.
  EXPECT_EQ(rec.tile_states().size(), 1u + 32u * 32u + 32u + 3u);
  const long grown_mib = (peak_rss_kib() - rss_before) / 1024;
  std::printf("peak memory grew by %ld MiB\n", grown_mib);
  EXPECT_LT(grown_mib, 512) << "peak memory grew by " << grown_mib << " MiB";
}

TEST(ExtremesTest, SampleStoreRingIndexesPastTwoToThe32Samples) {
  // Sequence numbers beyond 2^32 (a display running for days at 10^5 samples/s) map to the
  // same slots as a 64-bit modulo says, and the runs cover exactly the requested range.
  constexpr size_t kCapacity = (size_t(1) << 20) + 7;
  for (uint64_t first : {uint64_t(1) << 32, (uint64_t(1) << 32) - 3, uint64_t(5) << 40,
                         std::numeric_limits<uint64_t>::max() - kCapacity}) {
    for (uint64_t count : {uint64_t(1), uint64_t(100), uint64_t(kCapacity)}) {
      RingRun runs[2];
      const int k = ring_runs(first, first + count, kCapacity, runs);
      ASSERT_GE(k, 1);
      EXPECT_EQ(runs[0].slot, size_t(first % kCapacity));
      size_t covered = 0;
      for (int r = 0; r < k; ++r) {
        EXPECT_EQ(runs[r].offset, covered);
        EXPECT_LE(runs[r].slot + runs[r].count, kCapacity);
        covered += runs[r].count;
      }
      EXPECT_EQ(covered, count);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Tiles and filter

TEST(ExtremesTest, OnePixelTilesAtTheDisplayEqualOneTileOfTheSameValues) {
  // 4096 tiles of one pixel each, all with the same values and the same measured rate, give
  // bit for bit the image of one tile over the whole image; with random values per pixel the
  // image stays finite. R_l is measured per tile from the store (filter.h, step 0), so the
  // samples are stratified: every pixel holds exactly 4 of them (the store's N = 4 x pixels
  // keeps them all), and every one-pixel tile measures 4 / depth, the rate of the single tile
  // (4 x 4096 / (4096 x depth)).
  constexpr int kSide = 64, kPerPixel = 4;
  Pcg32 rng(4);
  SampleBatch batch;
  for (int k = 0; k < kPerPixel; ++k) {
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        Sample s;
        s.x = std::min(float(x) + rng.next_float(), std::nextafter(float(x + 1), 0.0f));
        s.y = std::min(float(y) + rng.next_float(), std::nextafter(float(y + 1), 0.0f));
        s.time = rng.next_double();
        s.color = glm::vec3(rng.next_float(), 0.5f, rng.next_float());
        batch.samples.push_back(s);
      }
    }
  }
  const auto tiling = [&](bool single_pixels, bool random_values) {
    TilingSnapshot t;
    t.region = PixelRect{0, 0, kSide, kSide};
    t.time = 1.0;
    const int side = single_pixels ? 1 : kSide;
    for (int y = 0; y < kSide; y += side) {
      for (int x = 0; x < kSide; x += side) {
        TileInfo info;
        info.rect = PixelRect{x, y, x + side, y + side};
        info.G_x = random_values ? rng.next_float() : 0.05f;
        info.G_y = random_values ? 1e-3f * rng.next_float() : 0.02f;
        info.G_t = random_values ? 10.0f * rng.next_float() : 0.3f;
        info.rate = random_values ? 1e4f * rng.next_float() : 7.0f;
        t.tiles.push_back(info);
      }
    }
    return t;
  };
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  Image images[3];
  float rates[3] = {0.0f, 0.0f, 0.0f};
  const bool cases[3][2] = {{false, false}, {true, false}, {true, true}};
  for (int k = 0; k < 3; ++k) {
    CpuReconstructor rec(rec_config(kSide, kSide));
    rec.add_batch(batch);
    rec.set_tiling(tiling(cases[k][0], cases[k][1]));
    images[k] = rec.reconstruct(cam, 1.0, kSide, kSide);
    EXPECT_EQ(rec.tiling_stats().dropped_tiles, 0u);
    EXPECT_EQ(rec.frame_stats().nonfinite_pixels, 0u);
    for (const glm::vec3& c : images[k].pixels) ASSERT_TRUE(finite3(c));
    // Every tile measured what it holds: 4 samples a pixel. The single tile is there as its
    // pieces on the rate lattice (tile_field.h), each with its own rate.
    const std::vector<TileState>& tiles = rec.tile_states();
    const size_t pieces = size_t(kSide / kRateLattice) * size_t(kSide / kRateLattice);
    ASSERT_EQ(tiles.size(), 1u + (cases[k][0] ? size_t(kSide) * kSide : pieces));
    for (size_t i = 1; i < tiles.size(); ++i) {
      ASSERT_EQ(tiles[i].stored, uint64_t(kPerPixel) * uint64_t(tiles[i].rect.area())) << i;
      ASSERT_EQ(tiles[i].rate, tiles[1].rate) << i;
    }
    if (k == 1) {
      EXPECT_EQ(tiles[1].rate, rates[0]);
    }
    rates[k] = tiles[1].rate;
  }
  for (size_t p = 0; p < images[0].pixels.size(); ++p) {
    ASSERT_EQ(images[0].pixels[p], images[1].pixels[p]) << p;
  }
}

TEST(ExtremesTest, FilterExtentsAtBothClampsGiveFiniteImages) {
  // Every combination of extreme gradients, rates and store depths gives extents inside the
  // documented clamps and within the 4:1 anisotropy cap, and reaches every corner of the
  // clamps the cap leaves reachable; tiles at the narrowest and widest clamps, upscaled 16x
  // and downscaled, reconstruct a uniform color exactly.
  const FilterLimits lim;
  const float kBig = std::numeric_limits<float>::max();
  const float kDenorm = std::numeric_limits<float>::denorm_min();
  const float gradients[] = {0.0f,   kDenorm,
                             1e-30f, lim.min_spatial_gradient,
                             1.0f,   lim.max_spatial_gradient,
                             1e30f,  kBig,
                             kInf,   kNaN,
                             -1.0f,  -kInf};
  const float rates[] = {0.0f, kDenorm, lim.min_rate, 1.0f, lim.max_rate, kBig, kInf, kNaN, -5.0f};
  const float depths[] = {
      0.0f, 1e-9f, lim.min_temporal_extent, 1.0f, lim.max_temporal_extent, 1e30f, kInf,
      kNaN, -1.0f};
  // Corners of (spatial, temporal) clamps reached: [spatial low/high][temporal low/high].
  bool hit[2][2] = {{false, false}, {false, false}};
  for (float gx : gradients) {
    for (float gy : gradients) {
      for (float gt : gradients) {
        for (float r : rates) {
          for (float d : depths) {
            const FilterExtents e = filter_extents(gx, gy, gt, r, d, lim);
            ASSERT_TRUE(e.e_x >= lim.min_spatial_extent && e.e_x <= lim.max_spatial_extent &&
                        e.e_y >= lim.min_spatial_extent && e.e_y <= lim.max_spatial_extent &&
                        e.e_t >= lim.min_temporal_extent && e.e_t <= lim.max_temporal_extent)
                << gx << " " << gy << " " << gt << " " << r << " " << d << ": " << e.e_x << " "
                << e.e_y << " " << e.e_t;
            const TileFilter f = make_tile_filter(e, 16.0f, 1.0f / 64.0f);
            ASSERT_TRUE(std::isfinite(f.k_t) && f.k_t > 0.0f && f.sigma_x > 0.0f &&
                        f.sigma_y > 0.0f);
            const float ratio = std::max(e.e_x / e.e_y, e.e_y / e.e_x);
            ASSERT_LE(ratio, lim.max_anisotropy * (1.0f + 1e-5f))
                << gx << " " << gy << " " << gt << " " << r << " " << d;
            const float e_s = std::max(e.e_x, e.e_y), e_s_low = std::min(e.e_x, e.e_y);
            for (int t = 0; t < 2; ++t) {
              if (e.e_t != (t ? lim.max_temporal_extent : lim.min_temporal_extent)) continue;
              hit[0][t] = hit[0][t] || e_s_low == lim.min_spatial_extent;
              hit[1][t] = hit[1][t] || e_s == lim.max_spatial_extent;
            }
          }
        }
      }
    }
  }
  // Sharp in space and time (dense, fast-changing), wide in space and sharp in time (sparse,
  // flat, fast-changing), sharp in space and long in time (dense, still, a deep store).
  EXPECT_TRUE(hit[0][0]);
  EXPECT_TRUE(hit[1][0]);
  EXPECT_TRUE(hit[0][1]);
  // Wide in space and long in time at once needs, under the cap, e_x at its largest, e_y >=
  // e_x / max_anisotropy and e_t at its largest: a volume V_s = e_x e_y e_t of at least
  // max^2 / max_anisotropy x max_t pixel seconds, while V_s = 1 / R_l <= 1 / min_rate (the
  // extents only shrink below the volume when clamped, never grow past it in both space and
  // time). It is reached exactly when the clamps allow that volume (at 16 px: 3840 > 1000,
  // out of reach; at 4 px: 240, reached).
  const bool wide_and_long = lim.max_spatial_extent * lim.max_spatial_extent / lim.max_anisotropy *
                                 lim.max_temporal_extent <=
                             1.0f / lim.min_rate;
  EXPECT_EQ(hit[1][1], wide_and_long);
  // The cutoff's own range is enforced; splat radii are clamped to what GL can draw.
  ReconstructorConfig bad = rec_config(16, 16);
  bad.filter.cutoff = 0.99f;
  EXPECT_THROW(CpuReconstructor{bad}, Error);
  bad.filter.cutoff = 8.01f;
  EXPECT_THROW(CpuReconstructor{bad}, Error);
  bad.filter.cutoff = kNaN;
  EXPECT_THROW(CpuReconstructor{bad}, Error);
  // Tiles at the clamps side by side, the widest with a cutoff of 8: reconstructed at the
  // sampling size, 16x larger (the splats' radius clamp) and 8x smaller. R_l is measured from
  // the store (filter.h, step 0), so the store is built to drive each tile to its clamps:
  // 8000 samples in the sharp tile (a still edge: G = max, G_t = 0), 2000 in the wide one (flat
  // and changing fast: G = 0, G_t = max). With a store reaching back 100 s (depth clamped to
  // 60 s) the sharp tile is at (0.3 px, 60 s) and the wide one at 16 px; with a store reaching
  // back 1 ms (the floor) the sharp tile is at (0.3 px, 1 ms) and the wide one at (16 px, 1 ms).
  constexpr int kSide = 32;
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  for (const double reach : {100.0, 1e-3}) {
    ReconstructorConfig cfg = rec_config(kSide, kSide);
    cfg.filter.cutoff = 8.0f;
    cfg.splat.max_radius = 1e9f;
    cfg.capacity = 10000;  // holds every sample below
    CpuReconstructor rec(cfg);
    EXPECT_EQ(rec.config().splat.max_radius, kSplatRadiusLimit);
    Pcg32 rng(8);
    SampleBatch batch;
    for (int i = 0; i < 10000; ++i) {
      Sample s;
      s.x = kSide / 2 * rng.next_float() + (i < 8000 ? 0.0f : kSide / 2);
      s.y = kSide * rng.next_float();
      s.time = 100.0 - reach * double(10000 - i) / 10000.0;  // in time order
      s.color = glm::vec3(0.125f, 0.5f, 2.0f);
      batch.samples.push_back(s);
    }
    rec.add_batch(batch);
    TilingSnapshot tiling;
    tiling.region = PixelRect{0, 0, kSide, kSide};
    tiling.time = 100.0;
    TileInfo narrow, wide;
    narrow.rect = PixelRect{0, 0, kSide / 2, kSide};
    narrow.G_x = narrow.G_y = kBig;  // as sharp as the clamps allow
    narrow.G_t = 0.0f;
    narrow.rate = kBig;
    wide.rect = PixelRect{kSide / 2, 0, kSide, kSide};
    wide.G_x = wide.G_y = 0.0f;  // as wide as they allow
    wide.G_t = kBig;
    wide.rate = 0.0f;
    tiling.tiles = {narrow, wide};
    rec.set_tiling(tiling);
    for (int out : {kSide, 16 * kSide, kSide / 8}) {
      const Image image = rec.reconstruct(cam, 100.0, out, out);
      EXPECT_EQ(rec.frame_stats().nonfinite_pixels, 0u) << out;
      EXPECT_EQ(rec.frame_stats().empty_pixels, 0u) << out;
      for (const glm::vec3& c : image.pixels) {
        ASSERT_NEAR(c.r, 0.125f, 1e-6f) << out;
        ASSERT_NEAR(c.b, 2.0f, 1e-5f) << out;
      }
      // The tiles reached the clamps they were built for.
      const std::vector<TileState>& tiles = rec.tile_states();
      ASSERT_EQ(tiles.size(), 3u);
      const FilterExtents sharp = tiles[1].extents, flat = tiles[2].extents;
      const float e_t = reach > 1.0 ? lim.max_temporal_extent : lim.min_temporal_extent;
      EXPECT_EQ(sharp.e_x, lim.min_spatial_extent) << reach;
      EXPECT_EQ(sharp.e_y, lim.min_spatial_extent) << reach;
      EXPECT_EQ(sharp.e_t, e_t) << reach;
      EXPECT_EQ(flat.e_x, lim.max_spatial_extent) << reach;
      EXPECT_EQ(flat.e_y, lim.max_spatial_extent) << reach;
      if (reach < 1.0) {
        EXPECT_EQ(flat.e_t, lim.min_temporal_extent);
      }
    }
  }
}

}  // namespace
}  // namespace afr
