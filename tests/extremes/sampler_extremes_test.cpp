// Numerical extremes of the sampler and the scene it traces: hours of virtual time, one-pixel
// tiles, the corner of a 32768-pixel image, degenerate and non-finite geometry, non-finite and
// huge radiance, and scenes a million times larger or smaller than a unit.
#include <afr/sampler/sampler.h>

#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/protocol/codec.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "extremes/extremes_support.h"
#include "support/base64.h"
#include "support/test_scenes.h"

namespace afr {
namespace {

using extremes::sample_is_sane;
using extremes::snapshot_is_sane;
using extremes::stats_match_buffer;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Checks everything the sampler emits as it arrives, and that the protocol encoder takes
// every batch and snapshot (what the network would do with them), keeping nothing.
struct CheckingSink : SampleSink {
  int width = 0, height = 0;
  uint64_t samples = 0, bad_samples = 0, snapshots = 0, bad_snapshots = 0;
  uint64_t refused_batches = 0;
  std::string first_problem;
  bool encode = true;
  std::vector<uint8_t> bytes;

  CheckingSink(int w, int h) : width(w), height(h) {}
  void note(const std::string& problem) {
    if (first_problem.empty()) first_problem = problem;
  }
  void on_batch(SampleBatch&& b) override {
    for (const Sample& s : b.samples) {
      ++samples;
      if (const ::testing::AssertionResult r = sample_is_sane(s, width, height); !r) {
        ++bad_samples;
        note(r.message());
      }
    }
    if (encode) {
      if (const protocol::Status st = protocol::encode(b, &bytes, {width, height}); !st) {
        ++refused_batches;
        note(st.message());
      }
    }
  }
  void on_tiling(TilingSnapshot&& s) override {
    ++snapshots;
    if (const ::testing::AssertionResult r = snapshot_is_sane(s); !r) {
      ++bad_snapshots;
      note(r.message());
    }
  }
  void expect_clean() const {
    EXPECT_GT(samples, 0u);
    EXPECT_EQ(bad_samples, 0u) << first_problem;
    EXPECT_EQ(bad_snapshots, 0u) << first_problem;
    EXPECT_EQ(refused_batches, 0u) << first_problem;
  }
};

SamplerConfig config(int w, int h, uint64_t seed = 11) {
  SamplerConfig c;
  c.image.width = w;
  c.image.height = h;
  c.seed = seed;
  return c;
}

// Static emissive quads of four different colors with edges at odd sub-pixel places: tiles
// across an edge have a variance that depends on where their crosshairs fell.
Scene static_quads_scene() {
  Scene s = testing::camera_scene();
  testing::add_quad(&s, glm::vec3(0.1f), {-10, -10}, {10, 10}, -2.0f);
  testing::add_quad(&s, glm::vec3(1.0f), {-10, -10}, {0.0123f, 10});
  testing::add_quad(&s, glm::vec3(0.2f, 0.8f, 0.4f), {0.1f, 0.07f}, {0.31f, 0.29f});
  testing::add_quad(&s, glm::vec3(3.0f, 0.5f, 0.0f), {-0.37f, -0.33f}, {-0.11f, -0.19f}, -0.9f);
  s.finalize();
  return s;
}

TEST(ExtremesTest, StaticSceneForTenHoursKeepsExactStatistics) {
  // 10 rays per virtual second: ten hours are ~360000 rays. Every weight underflows thousands
  // of times over; the running sums must still equal a fresh pass over the deep buffer. The
  // crosshairs of a tile are seconds apart, so the one that leaves it (or the sibling a split
  // subtracts) often held nearly all of its weight: what the subtraction leaves is rounding,
  // and the sampler must re-derive those sums before it reads them.
  const Scene scene = static_quads_scene();
  Tracer tracer(scene);
  VirtualClock clock(10.0);
  CheckingSink sink(24, 24);
  sink.encode = false;  // one snapshot per step: checking them is enough
  SamplerConfig cfg = config(24, 24);
  cfg.max_tiles = 48;
  Sampler sampler(scene, tracer, clock, cfg, sink);
  sampler.fill();
  int checks = 0;
  double next_check = 600.0;
  while (clock.now() < 10.0 * 3600.0) {
    sampler.step();
    for (int t : sampler.tiling().tiles()) ASSERT_GE(sampler.tile_stats(t).v, 0.0);
    if (clock.now() >= next_check) {
      ASSERT_TRUE(stats_match_buffer(sampler, clock.now())) << "at t = " << clock.now() << " s";
      ASSERT_TRUE(sampler.tiling().is_valid());
      next_check += 600.0;
      ++checks;
    }
  }
  EXPECT_GE(checks, 59);
  EXPECT_TRUE(stats_match_buffer(sampler, clock.now()));
  // There is something to compare: the edges keep some tiles' gradients well above zero.
  double max_g = 0.0;
  for (int t : sampler.tiling().tiles()) {
    max_g = std::max(max_g, sampler.tile_stats(t).G_x + sampler.tile_stats(t).G_y);
  }
  EXPECT_GT(max_g, 1e-2);
  EXPECT_GT(sampler.target_tiles(), 0);
  EXPECT_LE(sampler.target_tiles(), 48);
  sampler.flush();
  sink.expect_clean();
}

TEST(ExtremesTest, OnePixelTilesKeepExactStatistics) {
  // As many tiles as gain control allows (a quarter of the pixels) around one hard edge: the
  // tiles along it are split down to single pixels.
  const Scene scene = testing::edge_scene();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  CheckingSink sink(64, 64);
  SamplerConfig cfg = config(64, 64);
  cfg.region = PixelRect{16, 0, 48, 64};
  cfg.min_tiles = cfg.max_tiles = 32 * 64 / 4;
  cfg.max_tiling_ops = 8;
  Sampler sampler(scene, tracer, clock, cfg, sink);
  sampler.fill();
  for (int k = 0; k < 30000; ++k) sampler.step();
  sampler.flush();
  int one_pixel = 0;
  for (int t : sampler.tiling().tiles()) {
    const PixelRect r = sampler.tiling().node(t).rect;
    if (r.area() == 1) {
      ++one_pixel;
      EXPECT_LE(sampler.buffer().count(r.x0, r.y0), cfg.b);
    }
  }
  ASSERT_GT(one_pixel, 10) << "the edge did not split its tiles down to single pixels";
  ASSERT_TRUE(sampler.tiling().is_valid());
  EXPECT_TRUE(stats_match_buffer(sampler, clock.now()));
  sink.expect_clean();
}

TEST(ExtremesTest, SamplerAtTheCornerOf32768ImageAllocatesForItsRegionOnly) {
  // A sampler owning the 8 x 8 pixels at the far corner of a 32768 x 32768 image: memory for
  // those pixels only, and every sample it emits lies inside the image as a float (the protocol
  // refuses a batch with x >= width; a double just below 32768 rounds to 32768.0f, which
  // sampler.cpp's emit() guards against since d4a0d42).
  const Scene scene = testing::edge_scene();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  CheckingSink sink(32768, 32768);
  SamplerConfig cfg = config(32768, 32768);
  cfg.region = PixelRect{32760, 32760, 32768, 32768};
  Sampler sampler(scene, tracer, clock, cfg, sink);
  sampler.fill();
  for (int k = 0; k < 40000; ++k) sampler.step();
  sampler.flush();
  EXPECT_EQ(sampler.buffer().capacity(), 8 * 8 * cfg.b);
  EXPECT_TRUE(stats_match_buffer(sampler, clock.now()));
  sink.expect_clean();
}

// A quad made of triangles that are fine, of zero area, with repeated vertices, and one so
// thin that its normal underflows; in front of a lit wall.
Scene degenerate_scene() {
  Scene s = testing::camera_scene();
  Material lit;
  lit.base_color_factor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  lit.metallic = 0.0f;
  lit.roughness = 0.5f;
  s.materials.push_back(lit);
  Primitive p;
  p.material = 0;
  p.positions = {{-5, -5, -2},       {5, -5, -2},
                 {5, 5, -2},         {-5, 5, -2},  // the wall
                 {-0.2f, 0, -1},     {0, 0, -1},
                 {0.2f, 0, -1},     // collinear
                 {0.1f, 0.1f, -1},  // repeated below
                 {-0.3f, -0.3f, -1}, {0.3f, -0.3f + 1e-21f, -1},
                 {0.3f, -0.3f, -1}};
  p.indices = {0, 1, 2, 0, 2, 3,  // the wall
               4, 5, 6,           // zero area, three distinct collinear vertices
               7, 7, 7,           // one point
               4, 7, 7,           // a segment
               8, 9, 10};         // a needle: cross product ~1e-22
  s.meshes.push_back(Mesh{"degenerate", {p}});
  Node n;
  n.mesh = 0;
  s.nodes.push_back(n);
  Light light;
  light.intensity = 5.0f;
  s.lights.push_back(light);
  Node ln;
  ln.light = 0;
  ln.translation = glm::dvec3(0.3, 0.5, 0.0);
  s.nodes.push_back(ln);
  s.finalize();
  return s;
}

TEST(ExtremesTest, DegenerateTrianglesTraceFinite) {
  const Scene scene = degenerate_scene();
  // Generated normals of degenerate triangles fall back to a unit vector.
  for (const glm::vec3& n : scene.meshes[0].primitives[0].normals) {
    EXPECT_TRUE(extremes::finite3(n));
    EXPECT_NEAR(glm::length(n), 1.0f, 1e-5f);
  }
  Tracer tracer(scene);
  // Rays aimed straight at the degenerate triangles (their vertices and interiors) see either
  // the lit wall behind them or, through a vertex, the degenerate triangle itself, shaded with
  // a fallback normal: finite and lit either way.
  TraceStats stats;
  const Camera cam = tracer.camera();
  int through = 0;
  for (const glm::vec3 target :
       {glm::vec3(0, 0, -1), glm::vec3(-0.1f, 0, -1), glm::vec3(0.1f, 0.1f, -1),
        glm::vec3(-0.2f, 0, -1), glm::vec3(-0.05f, 0.05f, -1), glm::vec3(0.3f, -0.3f, -1),
        glm::vec3(0.0f, -0.3f, -1)}) {
    const ShadedSample s = tracer.trace(Ray{glm::vec3(cam.eye), glm::normalize(target)}, &stats);
    ASSERT_TRUE(s.hit);
    ASSERT_TRUE(extremes::finite3(s.color) && extremes::finite3(s.position));
    EXPECT_GT(luminance(s.color), 0.0f) << target.x << " " << target.y;
    if (std::abs(s.position.z + 2.0f) < 1e-4f) {
      ++through;
    } else {
      EXPECT_NEAR(s.position.z, -1.0f, 1e-4f);
    }
  }
  EXPECT_GE(through, 4);  // interior points of zero-area triangles are never hit
  VirtualClock clock(1e5);
  CheckingSink sink(48, 48);
  Sampler sampler(scene, tracer, clock, config(48, 48), sink);
  sampler.fill();
  for (int k = 0; k < 5000; ++k) sampler.step();
  sampler.flush();
  EXPECT_EQ(sampler.counters().sanitized, 0u);
  EXPECT_EQ(stats.sanitized, 0u);
  EXPECT_TRUE(stats_match_buffer(sampler, clock.now()));
  sink.expect_clean();
}

// A one-triangle glTF whose positions are `positions` (9 floats), buffer embedded.
std::filesystem::path write_triangle_gltf(const std::string& name, const float positions[9]) {
  std::vector<uint8_t> bin(36);
  std::memcpy(bin.data(), positions, 36);
  const std::string json =
      R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],)"
      R"("nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
      R"("accessors":[{"bufferView":0,"componentType":5126,"type":"VEC3","count":3}],)"
      R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36}],)"
      R"("buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,)" +
      testing::base64(bin) + R"("}]})";
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("afr_extremes_" + std::to_string(getpid()) + "_" + name);
  std::ofstream(path) << json;
  return path;
}

TEST(ExtremesTest, NonFiniteVertexPositionsAreALoadErrorNamingTheProblem) {
  const float good[9] = {0, 0, -1, 1, 0, -1, 0, 1, -1};
  const std::filesystem::path ok = write_triangle_gltf("ok.gltf", good);
  EXPECT_NO_THROW({
    const Scene s = load_gltf(ok);
    EXPECT_EQ(s.triangle_count(), 1u);
  });
  std::filesystem::remove(ok);
  for (const float bad : {kNaN, kInf, -kInf}) {
    float positions[9] = {0, 0, -1, 1, 0, -1, 0, 1, -1};
    positions[4] = bad;
    const std::filesystem::path path = write_triangle_gltf("bad.gltf", positions);
    try {
      load_gltf(path);
      ADD_FAILURE() << "a vertex " << bad << " loaded";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path.filename().string()), std::string::npos) << what;
      EXPECT_NE(what.find("NaN or infinite"), std::string::npos) << what;
    }
    std::filesystem::remove(path);
    // A scene built in code is checked by finalize() the same way.
    Scene s = testing::camera_scene();
    testing::add_quad(&s, glm::vec3(1.0f), {-1, -1}, {1, 1});
    s.meshes.back().primitives[0].positions[2].y = bad;
    EXPECT_THROW(s.finalize(), Error);
  }
}

TEST(ExtremesTest, NanAndInfRadianceIsSanitisedAndCounted) {
  // Four quads: NaN, +Inf and -Inf emission, and a lit one under a light of infinite
  // intensity. The tracer replaces every non-finite color and counts it; nothing non-finite
  // reaches the samples, the statistics or the snapshots.
  Scene s = testing::camera_scene();
  testing::add_quad(&s, glm::vec3(kNaN), {-10, -10}, {0, 0});
  testing::add_quad(&s, glm::vec3(kInf, 0.5f, 0.5f), {0, -10}, {10, 0});
  testing::add_quad(&s, glm::vec3(-kInf), {-10, 0}, {0, 10});
  testing::add_quad(&s, glm::vec3(0.0f), {0, 0}, {10, 10});
  s.materials.back().base_color_factor = glm::vec4(1.0f);
  Light light;
  light.intensity = kInf;
  s.lights.push_back(light);
  Node ln;
  ln.light = 0;
  ln.translation = glm::dvec3(0.5, 0.5, 0.0);
  s.nodes.push_back(ln);
  s.finalize();
  Tracer tracer(s);
  VirtualClock clock(1e5);
  CheckingSink sink(32, 32);
  Sampler sampler(s, tracer, clock, config(32, 32), sink);
  sampler.fill();
  for (int k = 0; k < 3000; ++k) sampler.step();
  sampler.flush();
  // Every primary ray that hit one of the three non-finite quadrants was sanitised.
  EXPECT_GT(sampler.counters().sanitized, clock.rays() / 2);
  EXPECT_LE(sampler.counters().sanitized, clock.rays());  // once per ray: only the color
  // +Inf is clamped to the brightest radiance, 65504: tiles of such samples.
  EXPECT_TRUE(stats_match_buffer(sampler, clock.now(), 1e-6, 65504.0));
  sink.expect_clean();
}

TEST(ExtremesTest, HugeFiniteRadianceKeepsStatisticsFinite) {
  // Finite radiance near the float limit passes the tracer's NaN/Inf check, but differences
  // and squares of it would overflow floats (the crosshair gradients and the snapshot's
  // variance): the tracer clamps colors to 65504, the largest half float.
  Scene s = testing::camera_scene();
  testing::add_quad(&s, glm::vec3(3e38f), {-10, -10}, {0.0123f, 10});
  testing::add_quad(&s, glm::vec3(0.0f), {0.0123f, -10}, {10, 10});
  s.finalize();
  Tracer tracer(s);
  VirtualClock clock(1e5);
  CheckingSink sink(32, 32);
  Sampler sampler(s, tracer, clock, config(32, 32), sink);
  sampler.fill();
  for (int k = 0; k < 3000; ++k) sampler.step();
  sampler.flush();
  for (int t : sampler.tiling().tiles()) {
    const TileStats st = sampler.tile_stats(t);
    ASSERT_TRUE(std::isfinite(st.v) && std::isfinite(st.G_x) && std::isfinite(st.G_y) &&
                std::isfinite(st.G_t) && std::isfinite(sampler.tile_error(t)))
        << "tile " << t;
  }
  sink.expect_clean();
}

// A floor lit by a point light, a blocker casting a shadow on it and an emissive patch, all
// scaled by `scale` (light intensity by scale^2, so the radiance does not change).
Scene lit_scene(double scale) {
  Scene s;
  s.source = "lit";
  CameraModel lens;
  lens.yfov = glm::radians(60.0);
  lens.znear = 0.01 * scale;
  s.cameras.push_back(lens);
  Node cam;
  cam.camera = 0;
  cam.translation = glm::dvec3(0.0, 0.0, 0.0);
  s.nodes.push_back(cam);
  Material diffuse;
  diffuse.base_color_factor = glm::vec4(0.9f, 0.7f, 0.5f, 1.0f);
  diffuse.metallic = 0.0f;
  diffuse.roughness = 0.6f;
  s.materials.push_back(diffuse);
  Material glow = diffuse;
  glow.base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
  glow.emissive = glm::vec3(0.3f, 0.6f, 1.0f);
  s.materials.push_back(glow);
  const auto quad = [&](int material, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
    Primitive p;
    const float k = float(scale);
    p.positions = {a * k, b * k, c * k, d * k};
    p.indices = {0, 1, 2, 0, 2, 3};
    p.material = material;
    s.meshes.push_back(Mesh{"quad", {p}});
    Node n;
    n.mesh = int(s.meshes.size()) - 1;
    s.nodes.push_back(n);
  };
  // The floor y = -1 facing up, the blocker a horizontal square above it, the patch a wall.
  quad(0, {-4, -1, 0}, {4, -1, 0}, {4, -1, -8}, {-4, -1, -8});
  quad(0, {-0.5f, -0.4f, -2.5f}, {0.5f, -0.4f, -2.5f}, {0.5f, -0.4f, -3.5f}, {-0.5f, -0.4f, -3.5f});
  quad(1, {-3, 0.2f, -6}, {-1, 0.2f, -6}, {-1, 1.5f, -6}, {-3, 1.5f, -6});
  Light light;
  light.intensity = float(20.0 * scale * scale);
  s.lights.push_back(light);
  Node ln;
  ln.light = 0;
  ln.translation = glm::dvec3(0.2, 1.5, -3.0) * scale;
  s.nodes.push_back(ln);
  s.finalize();
  return s;
}

std::vector<ShadedSample> trace_image(const Scene& scene, int w, int h, TraceStats* stats) {
  Tracer tracer(scene);
  const Camera cam = tracer.camera();
  std::vector<ShadedSample> image;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x)
      image.push_back(tracer.trace(cam.ray(x + 0.5, y + 0.5, w, h), stats));
  }
  return image;
}

TEST(ExtremesTest, LitSceneLooksTheSameAtEveryScale) {
  // The same scene in units a million times larger and smaller, with the light scaled to give
  // the same radiance: the images agree except at a few edge pixels. Secondary-ray offsets
  // and the light-distance guard are relative to the scene's size; absolute ones (5e-5, 1e-6)
  // would exceed a scene in micrometres, and its shadows and nearby lights would vanish.
  constexpr int kW = 64, kH = 48;
  TraceStats stats;
  const std::vector<ShadedSample> unit = trace_image(lit_scene(1.0), kW, kH, &stats);
  int shadowed = 0, lit = 0;
  for (const ShadedSample& s : unit) {
    if (!s.hit || std::abs(s.position.y + 1.0f) > 1e-4f) continue;  // the floor only
    (luminance(s.color) == 0.0f ? shadowed : lit) += 1;
  }
  ASSERT_GT(shadowed, 20) << "the reference shows no shadow to compare";
  ASSERT_GT(lit, 200);
  for (double scale : {1e6, 1e-6}) {
    const std::vector<ShadedSample> scaled = trace_image(lit_scene(scale), kW, kH, &stats);
    int differ = 0;
    for (size_t p = 0; p < unit.size(); ++p) {
      ASSERT_TRUE(extremes::finite3(scaled[p].color));
      const float d = glm::length(scaled[p].color - unit[p].color);
      if (d > 1e-3f * (1.0f + glm::length(unit[p].color))) ++differ;
    }
    EXPECT_LE(differ, kW * kH / 100) << "scale " << scale;
  }
  EXPECT_EQ(stats.sanitized, 0u);
}

}  // namespace
}  // namespace afr
