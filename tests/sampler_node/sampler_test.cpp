#include <afr/sampler/sampler.h>

#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "support/sampler_rig.h"
#include "support/test_scenes.h"
#include "support/tile_stats.h"

namespace afr {
namespace {

using testing::CollectingSink;
using testing::SamplerRig;

SamplerConfig small_config(int w, int h) {
  SamplerConfig c;
  c.image.width = w;
  c.image.height = h;
  c.seed = 7;
  return c;
}

// Mean over a band of columns of 1 / (area of the tile covering each pixel): tiles per pixel.
double tile_density(const Sampler& s, int32_t x0, int32_t x1) {
  const PixelRect r = s.tiling().region();
  double sum = 0.0;
  int64_t n = 0;
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = x0; x < x1; ++x) {
      sum += 1.0 / double(s.tiling().node(s.tiling().tile_at(x, y)).rect.area());
      ++n;
    }
  }
  return sum / double(n);
}

void expect_close(double incremental, double reference, double rel, const char* what) {
  const double tol = rel * std::max(std::abs(reference), 1e-6);
  EXPECT_NEAR(incremental, reference, tol) << what;
}

TEST(SamplerTest, FillCoversTheRegionAndEmitsEverySample) {
  SamplerConfig config = small_config(32, 16);
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  // One crosshair every 2 pixels in x and y.
  EXPECT_EQ(sampler.buffer().size(), 16 * 8);
  EXPECT_EQ(sampler.counters().samples, sink.samples.size());
  EXPECT_EQ(clock.rays(), 16u * 8u * 5u);
  EXPECT_GE(sampler.tiling().tile_count(), sampler.config().min_tiles);
  EXPECT_TRUE(sampler.tiling().is_valid());
}

TEST(SamplerTest, TilesConcentrateAtAnEdge) {
  SamplerConfig config = small_config(64, 64);
  config.max_tiles = 128;
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  Sampler& sampler = rig.sampler;  // not a structured binding: the lambda captures it
  sampler.fill();
  const auto edge_over_far = [&] {
    return tile_density(sampler, 28, 36) /
           (0.5 * (tile_density(sampler, 0, 8) + tile_density(sampler, 56, 64)));
  };
  // While the deep buffer fills, the undersampling term u keeps tiles spread over the pixels
  // with empty slots: measured 2.3x-3.0x the far tile density at the edge from 4000 to 48000
  // steps (m = 1, lambda 0.4). Once every slot is full (about 52000 steps here: far tiles of
  // some 800 pixels get one crosshair per step between them), u is 0 and the variance term
  // alone puts the tiles on the edge: 181x from then on.
  for (int k = 0; k < 20000; ++k) sampler.step();
  EXPECT_GE(edge_over_far(), 2.0) << "filling";
  for (int k = 0; k < 60000; ++k) sampler.step();
  ASSERT_TRUE(sampler.tiling().is_valid());
  EXPECT_EQ(sampler.buffer().size(), sampler.buffer().capacity());
  EXPECT_GE(edge_over_far(), 50.0) << "full, tiles " << sampler.tiling().tile_count();
}

// The leaves of the tiling with their blocks, before an adjustment changes it.
std::vector<std::pair<int, PixelRect>> leaves(const Sampler& s) {
  std::vector<std::pair<int, PixelRect>> out;
  for (int t : s.tiling().tiles()) out.emplace_back(t, s.tiling().node(t).rect);
  return out;
}

TEST(SamplerTest, TileErrorFollowsSection61OnAConstructedBuffer) {
  // After the fill of the edge scene every crosshair was traced at one time (equal weights),
  // is white (luminance 1) or black (0), and none is occluded: a tile holding n crosshairs of
  // which w are white has v = p (1 - p) with p = w / n, and u = 1 - min(1, m mean_empty /
  // (s b - n)). The error of section 6.1, E = s (kappa v / sum v + lambda u / sum u) (the
  // occlusion term is 0), computed here from counts alone, is what the sampler uses.
  SamplerConfig config = small_config(64, 64);
  config.max_tiling_ops = 1;
  config.kappa = 0.5;
  config.lambda = 0.3;
  config.m = 0.5;
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  Sampler& sampler = rig.sampler;
  sampler.fill();
  const auto before = leaves(sampler);
  ASSERT_EQ(before.size(), size_t(config.min_tiles));
  const double b = config.b;
  const DeepBuffer& buffer = sampler.buffer();
  const double mean_empty = double(buffer.capacity() - buffer.size()) / double(before.size());
  std::vector<double> v(before.size()), u(before.size()), area(before.size());
  double sum_v = 0.0, sum_u = 0.0;
  for (size_t k = 0; k < before.size(); ++k) {
    const PixelRect r = before[k].second;
    int n = 0, white = 0;
    for (int32_t y = r.y0; y < r.y1; ++y) {
      for (int32_t x = r.x0; x < r.x1; ++x) {
        for (int j = 0; j < buffer.count(x, y); ++j) {
          const Crosshair& c = buffer.at(x, y, j);
          ASSERT_TRUE(c.luminance == 0.0f || c.luminance == 1.0f) << c.luminance;
          ASSERT_FALSE(c.has(Crosshair::kOccluded));
          ++n;
          white += c.luminance == 1.0f ? 1 : 0;
        }
      }
    }
    ASSERT_GT(n, 0);
    const double p = double(white) / n;
    area[k] = double(r.area());
    v[k] = p * (1.0 - p);
    const double empty = area[k] * b - n;
    u[k] = 1.0 - std::min(1.0, config.m * mean_empty / empty);
    sum_v += v[k];
    sum_u += u[k];
  }
  ASSERT_GT(sum_v, 0.0);    // tiles on the edge
  ASSERT_GT(sum_u, 0.0);    // tiles larger than the mean: the fill split the edge's
  sampler.adjust_tiling();  // computes every error, then changes at most one split or merge
  int compared = 0;
  for (size_t k = 0; k < before.size(); ++k) {
    const int t = before[k].first;
    if (!sampler.tiling().node(t).is_leaf() || sampler.tiling().node(t).rect != before[k].second) {
      continue;  // the one split or merge
    }
    const double expected = area[k] * (config.kappa * v[k] / sum_v + config.lambda * u[k] / sum_u);
    EXPECT_NEAR(sampler.tile_error(t), expected, 1e-9 * expected + 1e-12) << "tile " << t;
    ++compared;
  }
  EXPECT_GE(compared, int(before.size()) - 2);
  // A still image: no temporal gradient, so gain control asks for the most tiles.
  EXPECT_EQ(sampler.target_tiles(), config.max_tiles);
}

TEST(SamplerTest, GainControlInTheLoopFollowsSection41) {
  // Gain control of section 4.1 solves dC/ds S = i dC/dt T for the tile width S, with dC/ds
  // and dC/dt the area-weighted mean gradients over the tiles and T their mean sample age;
  // the target count is pixels / S^2. Here from a brute-force pass over the deep buffer of a
  // sampler that has followed a moving object for a while.
  SamplerConfig config = small_config(64, 64);
  config.max_tiles = 1024;
  config.i = 0.3;  // S about 4 here (with the default 0.1 the count sits at max_tiles)
  SamplerRig rig(testing::moving_scene(), 2e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  while (clock.now() < 0.6) sampler.step();
  double area = 0.0, spatial = 0.0, temporal = 0.0, age = 0.0;
  const auto tiles = sampler.tiling().tiles();
  for (int t : tiles) {
    const TileStats st = testing::brute_force_stats(sampler, t, clock.now());
    const double s = double(sampler.tiling().node(t).rect.area());
    area += s;
    spatial += s * 0.5 * (st.G_x + st.G_y);
    temporal += s * st.G_t;
    age += st.mean_age;
  }
  const double S = config.i * (temporal / area) * (age / double(tiles.size())) / (spatial / area);
  const double expected =
      std::clamp(64.0 * 64.0 / (S * S), double(config.min_tiles), double(config.max_tiles));
  ASSERT_GT(expected, double(config.min_tiles));  // not at a bound: the formula decides
  ASSERT_LT(expected, double(config.max_tiles)) << "S = " << S;
  sampler.adjust_tiling();
  EXPECT_NEAR(sampler.target_tiles(), expected, 1.0) << "S = " << S;
}

TEST(SamplerTest, SmallTilesFollowAMovingObject) {
  SamplerConfig config = small_config(64, 64);
  config.max_tiles = 128;
  SamplerRig rig(testing::moving_scene(), 4e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  // Stop at two times with the square on opposite sides; the smallest tiles go with it.
  for (double stop : {1.25, 1.75}) {
    while (clock.now() < stop) sampler.step();
    tracer.set_time(clock.now());
    const Camera cam = tracer.camera();
    const glm::dvec3 center(scene.evaluate(clock.now()).world[2][3]);
    glm::dvec2 xy;
    ASSERT_TRUE(cam.project(glm::dvec3(center.x, center.y, -1.0), 64, 64, &xy, nullptr));
    const int32_t cx = std::clamp(int32_t(xy.x), 8, 56);
    const double at_object = tile_density(sampler, cx - 6, cx + 6);
    const int32_t away = cx < 32 ? 50 : 8;
    const double elsewhere = tile_density(sampler, away - 6, away + 6);
    EXPECT_GT(at_object, 2.0 * elsewhere) << "t=" << stop << " object column " << cx;
  }
}

TEST(SamplerTest, IncrementalStatisticsEqualBruteForceOverHoursOfVirtualTime) {
  // 200 rays per second: a million rays take well over an hour of virtual time, so old
  // weights underflow many times over.
  SamplerConfig config = small_config(24, 24);
  config.max_tiles = 32;
  SamplerRig rig(testing::moving_scene(), 200.0, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  uint64_t inserted = 0;
  while (inserted < 1000000) {
    sampler.step();
    inserted = sampler.counters().crosshairs + sampler.counters().reprojections;
    if (sink.samples.size() > 100000) sink.samples.clear();
  }
  EXPECT_GT(clock.now(), 3600.0);
  for (int t : sampler.tiling().tiles()) {
    const TileStats inc = sampler.tile_stats(t);
    const TileStats ref = testing::brute_force_stats(sampler, t, clock.now());
    ASSERT_EQ(inc.count, ref.count);
    EXPECT_GE(inc.v, 0.0);
    expect_close(inc.v, ref.v, 1e-6, "v");
    expect_close(inc.G_x, ref.G_x, 1e-6, "G_x");
    expect_close(inc.G_y, ref.G_y, 1e-6, "G_y");
    expect_close(inc.G_t, ref.G_t, 1e-6, "G_t");
    expect_close(inc.mean_age, ref.mean_age, 1e-6, "mean age");
    expect_close(inc.occluded, ref.occluded, 1e-6, "occluded");
  }
}

// Static vertical stripes 0.1 units wide, bright and dark in turn, two units in front of the
// camera; and a grey wall one unit in front, out of view at time 0, in front of the stripes
// from 150 s on and sliding right at 0.1 units per second.
Scene stripes_and_sliding_wall_scene() {
  Scene s = testing::camera_scene();
  Mesh stripes{"stripes", {}};
  for (int tone = 0; tone < 2; ++tone) {
    Material m;
    m.base_color_factor = glm::vec4(0, 0, 0, 1);
    m.metallic = 0.0f;
    m.emissive = glm::vec3(tone == 0 ? 0.1f : 1.0f);
    s.materials.push_back(m);
    Primitive p;
    p.material = int(s.materials.size()) - 1;
    for (int i = tone; i < 60; i += 2) {
      const float x0 = -3.0f + 0.1f * float(i), x1 = x0 + 0.1f;
      const uint32_t v = uint32_t(p.positions.size());
      p.positions.insert(p.positions.end(),
                         {{x0, -10, -2}, {x1, -10, -2}, {x1, 10, -2}, {x0, 10, -2}});
      p.indices.insert(p.indices.end(), {v, v + 1, v + 2, v, v + 2, v + 3});
    }
    stripes.primitives.push_back(p);
  }
  s.meshes.push_back(stripes);
  Node n;
  n.mesh = int(s.meshes.size()) - 1;
  s.nodes.push_back(n);
  AnimationChannel ch;
  ch.node = testing::add_quad(&s, glm::vec3(0.5f), {-50, -50}, {50, 50});
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 150.0, 10000.0};
  ch.values = {{0, 100, 0, 0}, {0, 0, 0, 0}, {0.1 * 9850.0, 0, 0, 0}};
  s.channels.push_back(ch);
  s.finalize();
  return s;
}

TEST(SamplerTest, StatisticsStayExactWhenTheCrosshairHoldingNearlyAllTheWeightLeaves) {
  // Half a ray per second: the fill (16 crosshairs of the stripes, at time 0) takes 160 s, so
  // a crosshair traced after it outweighs all of them by exp(3.47 * 160) ~ 1e241. It lands on
  // the sliding wall, and its reprojection carries it out of the region: taking its weight
  // out of the sums leaves 1 + 1e-241 - 1 = 0. The tile must still report, at once, the
  // statistics of the stripes' crosshairs, as a brute-force pass over its block gives them.
  SamplerConfig config = small_config(16, 16);
  config.region = PixelRect{6, 6, 10, 10};
  config.fill_step = 1;
  config.min_tiles = config.max_tiles = 1;
  config.r = 0;                   // reproject only when the test says so
  config.occlusion_rays = false;  // the wall hides the stripes: keep their crosshairs
  config.loop_animation = false;
  SamplerRig rig(stripes_and_sliding_wall_scene(), 0.5, config);
  // References, not a structured binding: the lambda below captures them (clang 14 cannot
  // capture a binding).
  Sampler& sampler = rig.sampler;
  const VirtualClock& clock = rig.clock;
  sampler.fill();
  ASSERT_EQ(sampler.tiling().tile_count(), 1);
  const int tile = sampler.tiling().tiles()[0];
  const auto expect_exact = [&](const char* when) {
    const TileStats inc = sampler.tile_stats(tile);
    const TileStats ref = testing::brute_force_stats(sampler, tile, clock.now());
    ASSERT_EQ(inc.count, ref.count) << when;
    const double pairs[][2] = {{inc.v, ref.v},
                               {inc.G_x, ref.G_x},
                               {inc.G_y, ref.G_y},
                               {inc.G_t, ref.G_t},
                               {inc.mean_age, ref.mean_age}};
    const char* names[] = {"v", "G_x", "G_y", "G_t", "mean age"};
    for (int k = 0; k < 5; ++k) {
      EXPECT_NEAR(pairs[k][0], pairs[k][1], 1e-6 * std::abs(pairs[k][1]) + 1e-9)
          << names[k] << " " << when;
    }
  };
  expect_exact("after the fill");
  const TileStats stripes = testing::brute_force_stats(sampler, tile, clock.now());
  ASSERT_EQ(stripes.count, 16);
  ASSERT_GT(stripes.v, 0.01);  // something to get wrong
  ASSERT_GT(stripes.G_x, 0.1);
  for (int round = 0; round < 5; ++round) {
    SCOPED_TRACE(round);
    sampler.step();  // one crosshair on the wall, the newest by far
    ASSERT_EQ(sampler.tile_stats(tile).count, 17);
    expect_exact("with the wall's crosshair");
    // Reproject until it is the one taken (the others are static and stay in their pixel).
    const uint64_t dropped = sampler.counters().reprojections_dropped;
    for (int k = 0; k < 1000 && sampler.counters().reprojections_dropped == dropped; ++k) {
      sampler.reproject(tile);
    }
    ASSERT_EQ(sampler.counters().reprojections_dropped, dropped + 1);
    expect_exact("after it left");
    EXPECT_NEAR(sampler.tile_stats(tile).v, stripes.v, 1e-9);
  }
}

TEST(SamplerTest, GainControlIsFiniteAndBoundedAtTheExtremes) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double cases[][3] = {
      {0, 0, 0},          {0, 1, 1},   {1, 0, 1},   {1, 1, 0},   {1e300, 1, 1}, {1, 1e300, 1e300},
      {1e-300, 1e300, 1}, {inf, 1, 1}, {1, inf, 1}, {nan, 1, 1}, {1, nan, nan}, {1e-20, 1e-20, 1}};
  for (const auto& c : cases) {
    const double n = gain_tile_count(c[0], c[1], c[2], 1.0, 65536.0, 16.0, 1024.0, 100.0);
    EXPECT_TRUE(std::isfinite(n)) << c[0] << " " << c[1] << " " << c[2];
    EXPECT_GE(n, 16.0);
    EXPECT_LE(n, 1024.0);
  }
  // No temporal change: the most tiles; no spatial change: the fewest.
  EXPECT_EQ(gain_tile_count(0.1, 0.0, 1.0, 1.0, 65536.0, 16.0, 1024.0, 100.0), 1024.0);
  EXPECT_EQ(gain_tile_count(0.0, 0.5, 1.0, 1.0, 65536.0, 16.0, 1024.0, 100.0), 16.0);
  // In between: S = i dC/dt T / dC/ds = 2 * 0.5 * 0.4 / 0.1 = 4 pixels -> 65536 / 16 tiles.
  EXPECT_NEAR(gain_tile_count(0.1, 0.5, 0.4, 2.0, 65536.0, 16.0, 8192.0, 100.0), 4096.0, 1e-6);
}

TEST(SamplerTest, SameSeedGivesTheSameSampleStream) {
  const Scene scene = make_builtin_scene();
  Tracer tracer_a(scene), tracer_b(scene);
  VirtualClock clock_a(1e5), clock_b(1e5);
  CollectingSink a, b;
  SamplerConfig config = small_config(48, 32);
  Sampler sa(scene, tracer_a, clock_a, config, a);
  Sampler sb(scene, tracer_b, clock_b, config, b);
  sa.fill();
  sb.fill();
  for (int k = 0; k < 3000; ++k) {
    sa.step();
    sb.step();
  }
  sa.flush();
  sb.flush();
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (size_t i = 0; i < a.samples.size(); ++i) {
    ASSERT_EQ(a.samples[i].time, b.samples[i].time) << i;
    ASSERT_EQ(a.samples[i].x, b.samples[i].x) << i;
    ASSERT_EQ(a.samples[i].color, b.samples[i].color) << i;
  }
  EXPECT_EQ(a.snapshots.size(), b.snapshots.size());
}

// Moves the camera (node 0 of testing::camera_scene) by (0.3, 0.1, 0) at t = 0.25 s, and
// finalizes the scene.
void add_camera_jump(Scene* scene) {
  AnimationChannel ch;
  ch.node = 0;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kStep;
  ch.times = {0.0, 0.25};
  ch.values = {{0, 0, 0, 0}, {0.3, 0.1, 0, 0}};
  scene->channels.push_back(ch);
  scene->finalize();
}

TEST(SamplerTest, ReprojectedCrosshairsLandWhereAFreshTraceSeesTheirPoint) {
  // A static wall and a square in front of it; the camera jumps sideways at t = 0.25 s and
  // then holds still, so every crosshair traced before the jump and moved after it was
  // moved by pure camera translation to where the final camera sees its point.
  Scene scene = testing::camera_scene();
  testing::add_quad(&scene, glm::vec3(0.5f), {-20, -20}, {20, 20}, -3.0f);
  testing::add_quad(&scene, glm::vec3(1.0f), {-0.5f, -0.5f}, {0.5f, 0.5f}, -2.0f);
  add_camera_jump(&scene);
  Tracer tracer(scene);
  VirtualClock clock(2e5);
  CollectingSink sink;
  SamplerConfig config = small_config(64, 64);
  config.loop_animation = false;
  Sampler sampler(scene, tracer, clock, config, sink);
  sampler.fill();
  while (clock.now() < 0.5) sampler.step();
  tracer.set_time(clock.now());
  const Camera cam = tracer.camera();
  int checked = 0;
  TraceStats stats;
  const PixelRect r = sampler.tiling().region();
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = r.x0; x < r.x1; ++x) {
      for (int k = 0; k < sampler.buffer().count(x, y); ++k) {
        const Crosshair& c = sampler.buffer().at(x, y, k);
        if (c.time >= 0.25 || !c.has(Crosshair::kCenterHit)) continue;
        glm::dvec2 xy;
        ASSERT_TRUE(cam.project(glm::dvec3(c.position), 64, 64, &xy, nullptr));
        // Traced before the jump and never moved: it sits where the old camera saw it.
        if (glm::length(xy - glm::dvec2(c.x, c.y)) > 1.0) continue;
        const ShadedSample fresh = tracer.trace(cam.ray(c.x, c.y, 64, 64), &stats);
        ASSERT_TRUE(fresh.hit);
        if (std::abs(luminance(fresh.color) - c.luminance) > 1e-4f) continue;  // now hidden
        glm::dvec2 fresh_xy;
        ASSERT_TRUE(cam.project(glm::dvec3(fresh.position), 64, 64, &fresh_xy, nullptr));
        EXPECT_LT(glm::length(fresh_xy - xy), 0.5);
        ++checked;
      }
    }
  }
  EXPECT_GT(sampler.counters().reprojections, 1000u);
  EXPECT_GT(checked, 50);
}

// An orthographic camera (ymag 1) at the origin looking down -Z: two squares of one size, one
// at 2 and one at 20 units, left and right of the center, and nothing behind the right half of
// the view but them.
Scene orthographic_scene() {
  Scene scene = testing::camera_scene();
  scene.cameras[0].ymag = 1.0;
  testing::add_quad(&scene, glm::vec3(0.5f), {-0.8f, -0.3f}, {-0.2f, 0.3f}, -2.0f);
  testing::add_quad(&scene, glm::vec3(1.0f), {0.2f, -0.3f}, {0.8f, 0.3f}, -20.0f);
  testing::add_quad(&scene, glm::vec3(0.25f), {-20.0f, -20.0f}, {0.0f, 20.0f}, -30.0f);
  return scene;
}

TEST(SamplerTest, AnOrthographicCameraSeesEqualSquaresAtAnyDepthAtOneSize) {
  for (bool orthographic : {true, false}) {
    Scene scene = orthographic_scene();
    if (!orthographic) scene.cameras[0].ymag = 0.0;
    scene.finalize();
    Tracer tracer(scene);
    const Camera camera = tracer.camera();
    ASSERT_EQ(camera.orthographic(), orthographic);
    // Pixels across the middle row that see each square.
    int near = 0, far = 0;
    TraceStats stats;
    for (int x = 0; x < 400; ++x) {
      const ShadedSample s = tracer.trace(camera.ray(x + 0.5, 100.5, 400, 200), &stats);
      near += s.hit && std::abs(s.color.r - 0.5f) < 1e-3f;
      far += s.hit && std::abs(s.color.r - 1.0f) < 1e-3f;
    }
    if (orthographic) {
      // 0.6 of the view's 4 units of width: 60 pixels each.
      EXPECT_NEAR(near, 60, 1);
      EXPECT_NEAR(far, 60, 1);
    } else {
      EXPECT_GT(near, 5 * far);
    }
  }
}

TEST(SamplerTest, AnOrthographicViewSendsMissesAsPointsThatReprojectToTheirPixels) {
  // The camera jumps right and up at t = 0.25 s and then holds still.
  Scene scene = orthographic_scene();
  add_camera_jump(&scene);
  SamplerConfig config = small_config(64, 64);
  config.loop_animation = false;
  SamplerRig rig(std::move(scene), 2e5, config);
  auto& [served, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  while (clock.now() < 0.5) sampler.step();

  // Every sample is a point that the camera of its time projects to where it was traced; the
  // misses lie far along their rays.
  tracer.set_time(0.0);
  const Camera before = tracer.camera();
  tracer.set_time(0.5);
  const Camera after = tracer.camera();
  ASSERT_TRUE(before.orthographic() && after.orthographic());
  size_t far_points = 0;
  for (const Sample& s : sink.samples) {
    ASSERT_FALSE(s.miss);
    if (std::abs(s.time - 0.25) < 1e-3) continue;
    glm::dvec2 xy;
    ASSERT_TRUE(
        (s.time < 0.25 ? before : after).project(glm::dvec3(s.position), 64, 64, &xy, nullptr));
    EXPECT_NEAR(xy.x, s.x, 0.01);
    EXPECT_NEAR(xy.y, s.y, 0.01);
    far_points += s.position.z < -50.0f;
  }
  EXPECT_GT(far_points, sink.samples.size() / 8);

  // Crosshairs traced before the jump, misses among them, were moved to where the camera now
  // projects their points: all by the same 9.6 x 3.2 pixels (0.3 and 0.1 of a 2-unit view).
  int moved = 0, moved_misses = 0;
  const PixelRect r = sampler.tiling().region();
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = r.x0; x < r.x1; ++x) {
      for (int k = 0; k < sampler.buffer().count(x, y); ++k) {
        const Crosshair& c = sampler.buffer().at(x, y, k);
        if (c.time >= 0.25) continue;
        glm::dvec2 now, then;
        ASSERT_TRUE(after.project(glm::dvec3(c.position), 64, 64, &now, nullptr));
        ASSERT_TRUE(before.project(glm::dvec3(c.position), 64, 64, &then, nullptr));
        if (glm::length(then - glm::dvec2(c.x, c.y)) < 0.01) continue;  // not moved yet
        EXPECT_NEAR(c.x, now.x, 0.01);
        EXPECT_NEAR(c.y, now.y, 0.01);
        EXPECT_NEAR(then.x - now.x, 9.6, 0.01);
        EXPECT_NEAR(now.y - then.y, 3.2, 0.01);
        ++moved;
        moved_misses += !c.has(Crosshair::kCenterHit);
      }
    }
  }
  EXPECT_GT(moved, 50);
  EXPECT_GT(moved_misses, 10);
}

// One animated mesh, `motion` moving its node: piece i of `pieces` (a convex polygon, taken
// as a triangle fan) glows i / pieces.size(), so a point's luminance names the piece it
// belongs to, and a fresh trace says which piece is at an image position.
Scene glowing_pieces_scene(const std::vector<std::vector<glm::vec3>>& pieces,
                           AnimationChannel motion) {
  Scene s = testing::camera_scene();
  Mesh mesh{"pieces", {}};
  for (size_t i = 0; i < pieces.size(); ++i) {
    Material m;
    m.base_color_factor = glm::vec4(0, 0, 0, 1);
    m.metallic = 0.0f;
    m.emissive = glm::vec3(float(i) / float(pieces.size()));
    s.materials.push_back(m);
    Primitive p;
    p.positions = pieces[i];
    for (uint32_t k = 1; k + 1 < uint32_t(pieces[i].size()); ++k) {
      p.indices.insert(p.indices.end(), {0u, k, k + 1});
    }
    p.material = int(s.materials.size()) - 1;
    mesh.primitives.push_back(p);
  }
  s.meshes.push_back(mesh);
  Node n;
  n.mesh = 0;
  s.nodes.push_back(n);
  motion.node = int(s.nodes.size()) - 1;
  s.channels.push_back(motion);
  s.finalize();
  return s;
}

// `strips` vertical strips one unit in front of the camera, wider than the view at every time
// of the test, sliding right at `speed` units per second.
Scene sliding_strips_scene(int strips, float strip_width, double speed) {
  std::vector<std::vector<glm::vec3>> pieces;
  for (int i = 0; i < strips; ++i) {
    const float x0 = (float(i) - 0.5f * float(strips)) * strip_width, x1 = x0 + strip_width;
    pieces.push_back({{x0, -10, -1}, {x1, -10, -1}, {x1, 10, -1}, {x0, 10, -1}});
  }
  AnimationChannel ch;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 10.0};
  ch.values = {{0, 0, 0, 0}, {10.0 * speed, 0, 0, 0}};
  return glowing_pieces_scene(pieces, ch);
}

// A disc of `sectors` equal sectors one unit in front of the camera, wider than the view,
// turning about the view axis at `spin` radians per second.
Scene spinning_sectors_scene(int sectors, double spin) {
  std::vector<std::vector<glm::vec3>> pieces;
  const float radius = 5.0f;
  for (int i = 0; i < sectors; ++i) {
    const double a0 = 2.0 * glm::pi<double>() * i / sectors;
    const double a1 = 2.0 * glm::pi<double>() * (i + 1) / sectors;
    pieces.push_back({{0, 0, -1},
                      {radius * float(std::cos(a0)), radius * float(std::sin(a0)), -1},
                      {radius * float(std::cos(a1)), radius * float(std::sin(a1)), -1}});
  }
  AnimationChannel ch;
  ch.path = AnimatedPath::kRotation;
  ch.interpolation = Interpolation::kLinear;  // slerp between keys 0.1 rad apart
  for (int k = 0; k <= 100; ++k) {
    const double t = 0.1 * k, half = 0.5 * spin * t;
    ch.times.push_back(t);
    ch.values.push_back({0.0, 0.0, std::sin(half), std::cos(half)});
  }
  return glowing_pieces_scene(pieces, ch);
}

// What move_crosshairs_and_check found.
struct MovedCrosshairs {
  uint64_t reprojections = 0;
  int checked = 0, misplaced = 0;
};

// A sampler of one tile over a size x size image of `scene` (every crosshair on a moving
// object whose points glow in classes of their luminance), filled at once, whose crosshairs
// are moved at each of `times`, many times each (reprojection picks pixels at random, so most
// move more than once). A move may only put a crosshair where its point is at the time of that
// move: counts those that sit where a fresh trace at the time each was traced, or at one of
// `times`, sees no point of its class (`apart(a, b)`: how many classes a luminance a is from
// b; 1 is allowed, for a point on a class boundary).
template <typename Apart>
MovedCrosshairs move_crosshairs_and_check(Scene scene, int size, std::vector<double> times,
                                          CrosshairMotion motion, Apart apart) {
  SamplerConfig config = small_config(size, size);
  config.crosshair_motion = motion;
  config.fill_step = 2;
  config.min_tiles = config.max_tiles = 1;
  config.r = 0;                   // moves only when the test says so
  config.occlusion_rays = false;  // nothing hides anything
  config.loop_animation = false;
  SamplerRig rig(std::move(scene), 2e5, config);
  Sampler& sampler = rig.sampler;
  VirtualClock& clock = rig.clock;
  Tracer& tracer = rig.tracer;
  sampler.fill();
  EXPECT_LT(clock.now(), 0.1);
  const int tile = sampler.tiling().tiles()[0];
  for (const double t : times) {
    clock.primary_rays_traced(uint64_t((t - clock.now()) * clock.rate()));
    for (int k = 0; k < 8 * size * size; ++k) sampler.reproject(tile);
  }
  // Whether a fresh trace at time t through image position (x, y) sees a point of the class
  // of luminance l.
  const auto sees = [&](double t, double x, double y, float l) {
    tracer.set_time(t);
    TraceStats stats;
    const ShadedSample fresh = tracer.trace(tracer.camera().ray(x, y, size, size), &stats);
    return fresh.hit && apart(luminance(fresh.color), l) <= 1;
  };
  MovedCrosshairs out;
  out.reprojections = sampler.counters().reprojections;
  const PixelRect r = sampler.tiling().region();
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = r.x0; x < r.x1; ++x) {
      for (int k = 0; k < sampler.buffer().count(x, y); ++k) {
        const Crosshair& c = sampler.buffer().at(x, y, k);
        EXPECT_TRUE(c.has(Crosshair::kCenterHit));
        bool placed = sees(c.time, c.x, c.y, c.luminance);
        for (const double t : times) placed = placed || sees(t, c.x, c.y, c.luminance);
        out.misplaced += placed ? 0 : 1;
        ++out.checked;
      }
    }
  }
  return out;
}

TEST(SamplerTest, CrosshairsMovedManyTimesSitWhereTheObjectIsNotFurther) {
  // Every crosshair lies on the sliding plane; it is moved at 1 s, then at 1.5 s. Counting the
  // motion again on a second move would carry it 2 v t1 or more from where it was traced, past
  // anything a single move reaches (v t2): 5 pixels, 2.7 strips beyond.
  constexpr int kStrips = 200;
  constexpr int kSize = 64;
  // A straight slide: both motions are exact.
  for (const CrosshairMotion motion : {CrosshairMotion::kVelocity, CrosshairMotion::kTransform}) {
    const MovedCrosshairs moved = move_crosshairs_and_check(
        sliding_strips_scene(kStrips, 0.036f, 0.2), kSize, {1.0, 1.5}, motion,
        [](float a, float b) {
          return std::abs(std::lround(a * kStrips) - std::lround(b * kStrips));
        });
    EXPECT_GT(moved.reprojections, uint64_t(2 * kSize * kSize));
    EXPECT_GT(moved.checked, kSize * kSize / 8);
    EXPECT_EQ(moved.misplaced, 0) << "of " << moved.checked << " crosshairs";
  }
}

TEST(SamplerTest, CrosshairsOnATurningObjectTurnWithIt) {
  // Every crosshair lies on the turning disc; it is moved at 0.5 s and at 1 s, when the disc
  // has turned 29 and 57 degrees. The disc's transform at the time of a move says where its
  // point is; extrapolating the point's velocity along a straight line instead would leave it
  // 12 degrees (3 sectors) behind at 1 s.
  constexpr int kSectors = 90;  // 4 degrees each
  constexpr int kSize = 64;
  const MovedCrosshairs moved = move_crosshairs_and_check(
      spinning_sectors_scene(kSectors, 1.0), kSize, {0.5, 1.0}, CrosshairMotion::kTransform,
      [](float a, float b) {
        const long d = std::abs(std::lround(a * kSectors) - std::lround(b * kSectors)) % kSectors;
        return std::min(d, kSectors - d);
      });
  EXPECT_GT(moved.reprojections, uint64_t(2 * kSize * kSize));
  EXPECT_GT(moved.checked, kSize * kSize / 8);
  EXPECT_EQ(moved.misplaced, 0) << "of " << moved.checked << " crosshairs";
}

TEST(SamplerTest, CrosshairsOnATurningObjectGoWhereTheDisplayMovesTheirSamples) {
  // The default motion: every point extrapolates its velocity, as the display moves a sample
  // (position + velocity x age). Each crosshair on the turning disc, moved at 0.5 s and 1 s,
  // sits where that puts its traced point at one of those times (or at its own, unmoved); the
  // point is what a fresh trace at the crosshair's time sees there. By 1 s the straight line
  // has left most of them 12 degrees behind the disc (CrosshairsOnATurningObjectTurnWithIt).
  constexpr int kSectors = 90;
  constexpr int kSize = 64;
  const std::vector<double> times = {0.5, 1.0};
  SamplerConfig config = small_config(kSize, kSize);
  config.fill_step = 2;
  config.min_tiles = config.max_tiles = 1;
  config.r = 0;
  config.occlusion_rays = false;
  config.loop_animation = false;
  ASSERT_EQ(config.crosshair_motion, CrosshairMotion::kVelocity);
  SamplerRig rig(spinning_sectors_scene(kSectors, 1.0), 2e5, config);
  Sampler& sampler = rig.sampler;
  sampler.fill();
  const int tile = sampler.tiling().tiles()[0];
  for (const double t : times) {
    rig.clock.primary_rays_traced(uint64_t((t - rig.clock.now()) * rig.clock.rate()));
    for (int k = 0; k < 8 * kSize * kSize; ++k) sampler.reproject(tile);
  }
  const Camera camera = rig.tracer.camera();  // the view does not move
  int checked = 0, moved = 0;
  const PixelRect r = sampler.tiling().region();
  for (int32_t y = r.y0; y < r.y1; ++y) {
    for (int32_t x = r.x0; x < r.x1; ++x) {
      for (int k = 0; k < sampler.buffer().count(x, y); ++k) {
        const Crosshair& c = sampler.buffer().at(x, y, k);
        ASSERT_TRUE(c.has(Crosshair::kCenterHit));
        const glm::dvec3 p0(c.position), v(c.velocity);
        // The kept point and velocity are a fresh trace's at the crosshair's time.
        glm::dvec2 traced_at;
        ASSERT_TRUE(camera.project(p0, kSize, kSize, &traced_at, nullptr));
        rig.tracer.set_time(c.time);
        TraceStats stats;
        const ShadedSample fresh =
            rig.tracer.trace(camera.ray(traced_at.x, traced_at.y, kSize, kSize), &stats);
        ASSERT_TRUE(fresh.hit);
        EXPECT_LT(glm::length(glm::dvec3(fresh.position) - p0), 1e-4);
        EXPECT_LT(glm::length(glm::dvec3(fresh.velocity) - v), 1e-3);
        // Where the display's extrapolation puts it at the time of its last move.
        bool placed = false;
        for (const double t : {c.time, times[0], times[1]}) {
          glm::dvec2 xy;
          if (camera.project(p0 + v * (t - c.time), kSize, kSize, &xy, nullptr) &&
              glm::length(xy - glm::dvec2(c.x, c.y)) < 1e-2) {
            placed = true;
            moved += t == c.time ? 0 : 1;
            break;  // the earliest time that fits (a point near the axis fits several)
          }
        }
        EXPECT_TRUE(placed) << "crosshair at (" << c.x << ", " << c.y << ")";
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, kSize * kSize / 8);
  EXPECT_GT(moved, checked / 2);
  // Off the disc, as far as the fresh traces at the moves' times see: the two motions differ.
  const MovedCrosshairs off = move_crosshairs_and_check(
      spinning_sectors_scene(kSectors, 1.0), kSize, times, CrosshairMotion::kVelocity,
      [](float a, float b) {
        const long d = std::abs(std::lround(a * kSectors) - std::lround(b * kSectors)) % kSectors;
        return std::min(d, kSectors - d);
      });
  EXPECT_GT(off.misplaced, off.checked / 4) << "of " << off.checked << " crosshairs";
}

TEST(SamplerTest, OcclusionRaysCatchAnObjectMovingInFront) {
  SamplerRig rig(testing::moving_scene(), 2e5, small_config(64, 64));
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  while (clock.now() < 1.0) sampler.step();
  EXPECT_GT(sampler.counters().occlusion_rays, 0u);
  EXPECT_GT(sampler.counters().occlusion_hits, 0u);
}

TEST(SamplerTest, AnOrthographicViewsOcclusionRaysRunAlongItsAxis) {
  // A still orthographic view of a wall 20 units away with a small square 2 units away in
  // front of its center: no point the view sees is hidden, though the lines from nearly all
  // of them to the eye itself cross the square.
  Scene scene = testing::camera_scene();
  scene.cameras[0].ymag = 1.0;
  testing::add_quad(&scene, glm::vec3(0.5f), {-20, -20}, {20, 20}, -20.0f);
  testing::add_quad(&scene, glm::vec3(1.0f), {-0.1f, -0.1f}, {0.1f, 0.1f}, -2.0f);
  scene.finalize();
  SamplerRig rig(std::move(scene), 2e5, small_config(64, 64));
  auto& [s, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  while (clock.now() < 0.5) sampler.step();
  EXPECT_GT(sampler.counters().occlusion_rays, 1000u);
  EXPECT_LT(sampler.counters().occlusion_hits, sampler.counters().occlusion_rays / 100);
}

TEST(SamplerTest, AnOrthographicViewAHairHighSamplesAndDropsWhatItCannotPlace) {
  // A view 2e-300 units high (glTF allows any ymag but 0), which then jumps 0.3 units aside:
  // every point it saw projects some 1e299 pixels away, beyond any pixel index, and its
  // crosshair is dropped.
  Scene scene = testing::camera_scene();
  scene.cameras[0].ymag = 1e-300;
  testing::add_quad(&scene, glm::vec3(0.5f), {-20, -20}, {20, 20}, -2.0f);
  add_camera_jump(&scene);
  SamplerConfig config = small_config(32, 32);
  config.loop_animation = false;
  SamplerRig rig(std::move(scene), 2e5, config);
  auto& [s, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  while (clock.now() < 0.5) sampler.step();
  for (const Sample& out : sink.samples) {
    ASSERT_TRUE(std::isfinite(out.x) && std::isfinite(out.y));
    ASSERT_TRUE(std::isfinite(out.color.r));
  }
  EXPECT_GT(sampler.counters().reprojections, 0u);
  EXPECT_GT(sampler.counters().reprojections_dropped, 0u);
  EXPECT_TRUE(sampler.tiling().is_valid());
}

TEST(SamplerTest, OcclusionsCountForTheirAgeNotForAsLongAsTheirCrosshairsStay) {
  // The square moves in front of the background until 2 s and then stands still: occlusions
  // happen until then, and stop soon after. The deep buffer is far from full at this
  // rate, so the crosshairs that replaced occluded ones stay in it; the occlusion term must
  // still fade with their age (section 6.1's |O| counts occlusions now), as the other
  // statistics do: counted by their number, they kept drawing samples to where a moving object
  // had been (docs/sampler.md, "The occlusion term").
  SamplerConfig config = small_config(64, 64);
  config.loop_animation = false;
  SamplerRig rig(testing::moving_scene(), 2e4, config);
  // References, not a structured binding: the lambda captures them.
  Sampler& sampler = rig.sampler;
  const VirtualClock& clock = rig.clock;
  sampler.fill();
  const auto flagged_and_counted = [&] {
    int flagged = 0;
    const PixelRect r = sampler.tiling().region();
    for (int32_t y = r.y0; y < r.y1; ++y) {
      for (int32_t x = r.x0; x < r.x1; ++x) {
        for (int k = 0; k < sampler.buffer().count(x, y); ++k) {
          flagged += sampler.buffer().stats(x, y, k).has(Crosshair::kOccluded) ? 1 : 0;
        }
      }
    }
    double counted = 0.0;
    for (int t : sampler.tiling().tiles()) counted += sampler.tile_stats(t).occluded;
    return std::make_pair(flagged, counted);
  };
  while (clock.now() < 1.9) sampler.step();
  const auto [flagged_moving, counted_moving] = flagged_and_counted();
  ASSERT_GT(flagged_moving, 10);
  // The newest of them weigh about 1: a good part of the count is recent, and the occlusion
  // term takes a share of the error.
  EXPECT_GT(counted_moving, 0.1 * flagged_moving);
  EXPECT_GT(sampler.occlusion_share(), 0.05);
  // On until no occlusion has happened for 2 s.
  uint64_t hits = sampler.counters().occlusion_hits;
  double last_hit = clock.now();
  while (clock.now() < 60.0 && clock.now() - last_hit < 2.0) {
    sampler.step();
    if (sampler.counters().occlusion_hits != hits) {
      hits = sampler.counters().occlusion_hits;
      last_hit = clock.now();
    }
  }
  const double quiet = clock.now() - last_hit;
  ASSERT_GE(quiet, 2.0) << "occlusions went on until " << last_hit << " s";
  const auto [flagged_still, counted_still] = flagged_and_counted();
  ASSERT_GT(flagged_still, 10) << "the buffer still holds some";
  // Each counts at most exp(-3.47 x quiet), about 1e-3 of itself.
  EXPECT_LE(counted_still, flagged_still * std::exp(-kAgeDecay * quiet) * (1.0 + 1e-9));
  // ... and they no longer draw the error to where the square used to pass.
  EXPECT_LT(sampler.occlusion_share(), 0.01);
  for (int t : sampler.tiling().tiles()) {
    expect_close(sampler.tile_stats(t).occluded,
                 testing::brute_force_stats(sampler, t, clock.now()).occluded, 1e-6, "occluded");
  }
}

TEST(SamplerTest, OnePixelRegionWorks) {
  SamplerConfig config = small_config(64, 64);
  config.region = PixelRect{31, 40, 32, 41};
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  for (int k = 0; k < 2000; ++k) sampler.step();
  EXPECT_EQ(sampler.tiling().tile_count(), 1);
  EXPECT_LE(sampler.buffer().size(), 4);
  sampler.flush();
  for (const Sample& s : sink.samples) {
    EXPECT_TRUE(std::isfinite(s.color.r));
    EXPECT_GE(s.x, 29.0f);  // crosshair neighbours reach one pixel out
    EXPECT_LE(s.x, 33.0f);
  }
}

TEST(SamplerTest, HugeImageWithSmallRegionAllocatesForTheRegionOnly) {
  SamplerConfig config = small_config(32768, 32768);
  config.region = PixelRect{16000, 16000, 16064, 16032};
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  for (int k = 0; k < 2000; ++k) sampler.step();
  EXPECT_EQ(sampler.buffer().capacity(), 64 * 32 * 4);
  sampler.flush();
  for (const Sample& s : sink.samples) {
    EXPECT_GE(s.x, 15999.0f);
    EXPECT_LT(s.x, 16065.0f);
  }
}

TEST(SamplerTest, SamplesInTheLastPixelOfAHugeImageStayInsideIt) {
  // Near x = 32768 a float's spacing is 1/256 px: a position just short of the image edge
  // rounds up to it unless the sampler keeps it inside (the codec rejects x = width).
  SamplerConfig config = small_config(32768, 32768);
  config.region = PixelRect{32766, 32766, 32768, 32768};
  SamplerRig rig(testing::edge_scene(), 1e5, config);
  auto& [scene, tracer, clock, sink, sampler] = rig;
  sampler.fill();
  for (int k = 0; k < 4000; ++k) sampler.step();
  sampler.flush();
  ASSERT_GT(sink.samples.size(), 4000u);
  for (const Sample& s : sink.samples) {
    ASSERT_LT(s.x, 32768.0f);
    ASSERT_LT(s.y, 32768.0f);
  }
}

TEST(SamplerTest, AllBlackSceneStaysFinite) {
  Scene scene = testing::camera_scene();
  testing::add_quad(&scene, glm::vec3(0.0f), {-10, -10}, {10, 10});
  scene.finalize();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  CollectingSink sink;
  Sampler sampler(scene, tracer, clock, small_config(32, 32), sink);
  sampler.fill();
  for (int k = 0; k < 5000; ++k) sampler.step();
  for (int t : sampler.tiling().tiles()) {
    const TileStats st = sampler.tile_stats(t);
    EXPECT_EQ(st.v, 0.0);
    EXPECT_TRUE(std::isfinite(sampler.tile_error(t)));
  }
  for (const TilingSnapshot& snap : sink.snapshots) {
    for (const TileInfo& info : snap.tiles) {
      EXPECT_TRUE(std::isfinite(info.rate) && std::isfinite(info.E) && std::isfinite(info.G_t));
    }
  }
}

TEST(SamplerTest, NonFiniteShadingIsSanitisedAndCounted) {
  Scene scene = testing::camera_scene();
  testing::add_quad(&scene, glm::vec3(std::numeric_limits<float>::quiet_NaN()), {-10, -10},
                    {10, 10});
  scene.finalize();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  CollectingSink sink;
  Sampler sampler(scene, tracer, clock, small_config(16, 16), sink);
  sampler.fill();
  for (int k = 0; k < 200; ++k) sampler.step();
  sampler.flush();
  EXPECT_GT(sampler.counters().sanitized, 0u);
  for (const Sample& s : sink.samples) {
    EXPECT_TRUE(std::isfinite(s.color.r) && std::isfinite(s.color.g) && std::isfinite(s.color.b));
  }
  for (int t : sampler.tiling().tiles()) EXPECT_TRUE(std::isfinite(sampler.tile_stats(t).v));
}

TEST(SamplerTest, BaselinesSampleUniformly) {
  const Scene scene = testing::edge_scene();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  CollectingSink sink;
  SamplerConfig config = small_config(8, 4);
  config.mode = SamplerMode::kFramedSweep;
  Sampler sweep(scene, tracer, clock, config, sink);
  sweep.fill();
  for (int k = 0; k < 64; ++k) sweep.step();
  sweep.flush();
  ASSERT_EQ(sink.samples.size(), 64u);
  for (int k = 0; k < 64; ++k) {
    EXPECT_EQ(sink.samples[k].x, float(k % 8) + 0.5f);
    EXPECT_EQ(sink.samples[k].y, float((k / 8) % 4) + 0.5f);
  }
  // Uniform random: every pixel of a small image is hit about equally often.
  CollectingSink uniform_sink;
  config.mode = SamplerMode::kUniformRandom;
  Sampler uniform(scene, tracer, clock, config, uniform_sink);
  uniform.fill();
  for (int k = 0; k < 32000; ++k) uniform.step();
  uniform.flush();
  std::vector<int> hits(32, 0);
  for (const Sample& s : uniform_sink.samples) ++hits[int(s.y) * 8 + int(s.x)];
  for (int h : hits) EXPECT_NEAR(h, 1000, 150);
}

TEST(SamplerTest, ConfigOutOfRangeIsAClearError) {
  SamplerConfig c;
  c.kappa = 0.8;
  c.lambda = 0.5;
  try {
    c.validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lambda"), std::string::npos);
  }
  SamplerConfig d;
  d.region = PixelRect{0, 0, 300, 10};
  EXPECT_THROW(d.validate(), Error);
  SamplerConfig e;
  e.b = 0;
  EXPECT_THROW(e.validate(), Error);
}

}  // namespace
}  // namespace afr

namespace afr {
namespace {

TEST(SamplerTest, AdjustmentSplitsTheLargestErrorAndMergesTheSmallestPair) {
  const Scene scene = testing::edge_scene();
  Tracer tracer(scene);
  VirtualClock clock(1e5);
  testing::CollectingSink sink;
  SamplerConfig config = small_config(64, 64);
  config.min_tiles = config.max_tiles = 64;  // the count stays: every adjustment balances
  config.chunk = 1000000;                    // adjust only when the test says so
  config.max_tiling_ops = 1;
  Sampler sampler(scene, tracer, clock, config, sink);
  sampler.fill();
  int checked = 0;
  for (int round = 0; round < 40; ++round) {
    for (int k = 0; k < 300; ++k) sampler.step();
    const KdTiling& t = sampler.tiling();
    const std::vector<int> before = t.tiles();
    std::vector<std::array<int, 3>> pairs;  // parent and children that could merge
    for (int p : t.mergeable()) pairs.push_back({p, t.node(p).child[0], t.node(p).child[1]});
    sampler.adjust_tiling();
    const std::vector<int>& after = t.tiles();
    const auto in = [](const std::vector<int>& v, int x) {
      return std::find(v.begin(), v.end(), x) != v.end();
    };
    // The split tile left the cut and now has two leaf children; the merged parent joined
    // the cut. (Node ids are reused, so compare by role, not only by id.)
    int split = -1;
    for (int x : before) {
      if (!in(after, x) && !t.node(x).is_leaf()) split = x;
    }
    if (split == -1) continue;  // errors were already balanced: nothing to check
    const int sa = t.node(split).child[0], sb = t.node(split).child[1];
    int merged = -1;
    for (int x : after) {
      if (!in(before, x) && x != sa && x != sb) merged = x;
    }
    ASSERT_TRUE(t.is_valid());
    // The errors of this adjustment stay stored for the tiles it did not touch.
    for (int x : before) {
      if (x == sa || x == sb || !in(after, x) || !t.can_split(x)) continue;
      if (merged != -1 && t.node(x).parent == merged) continue;
      EXPECT_GE(sampler.tile_error(split), sampler.tile_error(x));
    }
    ASSERT_NE(merged, -1);
    // A merge stores the pair's summed error on the parent.
    const double merged_sum = sampler.tile_error(merged);
    for (const auto& p : pairs) {
      if (p[0] == merged || p[1] == sa || p[1] == sb || p[2] == sa || p[2] == sb) continue;
      if (!in(after, p[1]) || !in(after, p[2]) || t.node(p[1]).parent != p[0]) continue;
      EXPECT_LE(merged_sum, sampler.tile_error(p[1]) + sampler.tile_error(p[2]) + 1e-12);
    }
    ++checked;
  }
  EXPECT_GT(checked, 5);
}

// A clock that reads `tick` seconds later at every reading, as a wall clock reads around work
// that takes that long.
class TickingClock final : public Clock {
 public:
  explicit TickingClock(double tick) : tick_(tick) {}
  double now() const override { return now_ += tick_; }

 private:
  double tick_;
  mutable double now_ = 0.0;
};

TEST(SamplerTest, ACostlyMoveToANewSceneTimeSpacesOutTheNext) {
  // Under a clock of 4 ms a reading, moving the scene to a new time appears to take 4 ms: the
  // next move waits 8 x 4 ms, so that moving takes no more than about 1/9 of the sampler's
  // time. Under a clock of 10 us a reading the move is cheap and the scene time follows the
  // clock in steps of animation_step (1 ms), as before. The samples say which time they were
  // traced at.
  struct Case {
    double tick, min_spacing;
  };
  for (const Case c : {Case{4e-3, 8.0 * 4e-3}, Case{1e-5, 1e-3}}) {
    const Scene scene = testing::moving_scene();
    Tracer tracer(scene);
    TickingClock clock(c.tick);
    CollectingSink sink;
    Sampler sampler(scene, tracer, clock, small_config(32, 32), sink);
    sampler.fill();
    for (int k = 0; k < 3000; ++k) sampler.step();
    sampler.flush();
    std::vector<double> times;
    for (const Sample& s : sink.samples) times.push_back(s.time);
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
    ASSERT_GE(times.size(), 5u) << "tick " << c.tick;
    for (size_t i = 1; i < times.size(); ++i) {
      EXPECT_GE(times[i] - times[i - 1], c.min_spacing * (1.0 - 1e-9))
          << "tick " << c.tick << ", times " << times[i - 1] << " and " << times[i];
    }
  }
}

}  // namespace
}  // namespace afr
