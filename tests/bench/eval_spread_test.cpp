// Several seeds per table cell, and differences called only beyond their spread; animations of
// any scene, of which the kitchen's and the built-in scene's are presets.
#include <afr/common/camera_path.h>
#include <afr/common/error.h>
#include <afr/eval/animations.h>
#include <afr/eval/evaluation.h>
#include <afr/eval/report.h>
#include <afr/eval/sweep.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>

namespace afr::eval {
namespace {

RunResult run_with(Method method, double rate, uint64_t seed, double mean_rms) {
  RunResult r;
  r.method = method;
  r.rate = rate;
  r.seed = seed;
  r.mean_rms = mean_rms;
  r.stats.sample_seconds = 1.0;
  r.stats.primary_rays = 100 * seed;
  return r;
}

TEST(SpreadTest, CellsGiveMeanAndRangeOverSeedsAndDifferencesCountBeyondTheSpread) {
  AnimationResult a;
  a.spec.name = "test";
  for (const auto& [seed, rms] : {std::pair{1, 10.0}, {2, 12.0}, {3, 11.0}}) {
    a.runs.push_back(run_with(Method::kAdaptive, 4e5, seed, rms));
  }
  for (const auto& [seed, rms] : {std::pair{1, 11.5}, {2, 13.0}, {3, 14.0}}) {
    a.runs.push_back(run_with(Method::kFrameless, 4e5, seed, rms));
  }
  a.runs.push_back(run_with(Method::kFramed60, 4e5, 1, 20.0));
  a.runs.push_back(run_with(Method::kFramedTaa, 4e5, 1, 9.0));
  const std::vector<Cell> cells = cells_of(a);
  ASSERT_EQ(cells.size(), 4u);
  const auto cell = [&](Method m) {
    for (const Cell& c : cells) {
      if (c.method == m) return c;
    }
    ADD_FAILURE() << method_name(m);
    return Cell{};
  };
  const Cell adaptive = cell(Method::kAdaptive);
  EXPECT_EQ(adaptive.runs, 3);
  EXPECT_DOUBLE_EQ(adaptive.mean, 11.0);
  EXPECT_DOUBLE_EQ(adaptive.min, 10.0);
  EXPECT_DOUBLE_EQ(adaptive.max, 12.0);
  EXPECT_DOUBLE_EQ(adaptive.primary_rays, 200.0);
  // 10-12 against 11.5-14: the ranges overlap, so no win although the mean is lower.
  EXPECT_EQ(compare(adaptive, cell(Method::kFrameless)), Comparison::kWithinSpread);
  EXPECT_EQ(compare(adaptive, cell(Method::kFramed60)), Comparison::kLower);
  EXPECT_EQ(compare(adaptive, cell(Method::kFramedTaa)), Comparison::kHigher);
  const std::string table = comparison_markdown({a});
  EXPECT_NE(table.find("within spread (11.0 vs 12.8)"), std::string::npos) << table;
  EXPECT_NE(table.find("**lower** (11.0 vs 20.0)"), std::string::npos) << table;
  EXPECT_NE(table.find("**higher** (11.0 vs 9.0)"), std::string::npos) << table;
  EXPECT_NE(rms_table_markdown({a}).find("11.0 (10.0-12.0)"), std::string::npos);
}

EvalConfig tiny_config() {
  EvalConfig config;
  config.rates = {2e5};
  config.seconds = 3.0 / 60.0;
  config.ideal_spp = 1;
  config.base.width = 32;
  config.base.height = 24;
  config.base.warmup = 0.1;
  config.base.threads = 1;
  config.progress = false;
  config.jobs = 1;
  return config;
}

TEST(SpreadTest, EvaluateRunsEverySeededMethodOncePerSeed) {
  EvalConfig config = tiny_config();
  config.animations = {scene_animation("", "own", 2.0)};
  config.methods = {Method::kAdaptive, Method::kFramed60, Method::kFramedFullRes};
  config.seeds = 3;
  config.base.seed = 7;
  const std::vector<AnimationResult> results = evaluate(config);
  ASSERT_EQ(results.size(), 1u);
  std::map<Method, std::vector<uint64_t>> seeds;
  std::set<double> adaptive_rms;
  for (const RunResult& r : results[0].runs) {
    seeds[r.method].push_back(r.seed);
    if (r.method == Method::kAdaptive) adaptive_rms.insert(r.mean_rms);
  }
  EXPECT_EQ(seeds[Method::kAdaptive], (std::vector<uint64_t>{7, 8, 9}));
  EXPECT_EQ(seeds[Method::kFramedFullRes], (std::vector<uint64_t>{7, 8, 9}));
  EXPECT_EQ(seeds[Method::kFramed60], (std::vector<uint64_t>{7}));
  EXPECT_GE(adaptive_rms.size(), 2u) << "the seeds changed nothing";
}

TEST(AnimationsTest, PresetsAreScenesWithCamerasAndStartTimes) {
  const PresetFiles files{"k/kitchen.gltf", "p"};
  const AnimationSpec toycar = animation_preset("toycar", files);
  EXPECT_EQ(toycar.name, "toycar");
  EXPECT_EQ(toycar.scene, std::filesystem::path("k/kitchen.gltf"));
  EXPECT_EQ(toycar.camera_path, std::filesystem::path("p/toycar.path"));
  EXPECT_EQ(toycar.start, 11.0);
  const AnimationSpec bart = animation_preset("bart", files);
  EXPECT_TRUE(bart.camera_path.empty());
  EXPECT_EQ(bart.start, 8.5);
  EXPECT_TRUE(animation_preset("builtin", files).scene.empty());
  EXPECT_THROW(animation_preset("kitchen", files), Error);
  const AnimationSpec city = scene_animation("x/city.glb", "own", 4.0);
  EXPECT_EQ(city.name, "city");
  EXPECT_TRUE(city.camera_path.empty());
  EXPECT_EQ(city.start, 4.0);
  EXPECT_EQ(scene_animation("x/city.glb", "fly.path", 0.0).camera_path,
            std::filesystem::path("fly.path"));
}

// A glTF file from outside the evaluation's presets, with its own camera and with a camera
// path written here.
TEST(AnimationsTest, AnyGltfSceneRunsWithItsOwnCameraOrACameraPath) {
  const std::filesystem::path scene =
      std::filesystem::path(AFR_SOURCE_DIR) / "tests/service/data/static_scene.gltf";
  const std::filesystem::path path =
      std::filesystem::path(::testing::TempDir()) / "eval_spread_test_fly.path";
  // The scene camera's pose, then sideways at 6 m/s (about a pixel per frame here).
  std::vector<CameraKey> keys(2);
  for (CameraKey& k : keys) k.rotation = glm::dquat(0.9848078, -0.1736482, 0.0, 0.0);
  keys[0].time = 0.0;
  keys[0].eye = glm::dvec3(0.3, 1.4, 2.2);
  keys[1].time = 1.0;
  keys[1].eye = glm::dvec3(6.3, 1.4, 2.2);
  write_camera_path(CameraPath(keys), path);
  EvalConfig config = tiny_config();
  config.methods = {Method::kAdaptive, Method::kFramed60};
  config.seeds = 1;
  config.animations = {scene_animation(scene, "own", 0.5),
                       scene_animation(scene, path.string(), 0.5)};
  const std::vector<AnimationResult> results = evaluate(config);
  ASSERT_EQ(results.size(), 2u);
  for (const AnimationResult& a : results) {
    EXPECT_EQ(a.spec.name, "static_scene");
    ASSERT_EQ(a.runs.size(), 2u);
    for (const RunResult& r : a.runs) {
      EXPECT_TRUE(std::isfinite(r.mean_rms)) << method_name(r.method);
      EXPECT_EQ(r.rms.size(), 3u);
    }
  }
  // The path moves the camera; the scene's own one stands still: the framed renderer's frames
  // are older than the ideal ones, which shows only where the view moves.
  EXPECT_EQ(results[0].runs[1].method, Method::kFramed60);
  EXPECT_LT(results[0].runs[1].mean_rms, results[1].runs[1].mean_rms);
}

// A sweep point is the mean and range of its seeds' runs; it differs from the defaults only
// beyond the spread, and the Pareto front is taken on the means.
TEST(SpreadTest, SweepPointsGiveMeanAndRangeOverSeedsAgainstTheDefaults) {
  const auto runs = [](std::initializer_list<double> rms, double sample_seconds) {
    std::vector<RunResult> out;
    for (double v : rms) {
      RunResult r = run_with(Method::kAdaptive, 4e5, out.size() + 1, v);
      r.animation = "test";
      r.stats.virtual_seconds = 2.0;
      r.stats.sample_seconds = sample_seconds;
      r.stats.reconstruct_seconds = 0.5;
      out.push_back(r);
    }
    return out;
  };
  const SweepPoint defaults{"default", "defaults", Method::kAdaptive, 4e5, nullptr};
  const SweepPoint b1{"b", "b=1", Method::kAdaptive, 4e5, nullptr};
  const SweepPoint r0{"r", "r=0", Method::kAdaptive, 4e5, nullptr};
  const SweepPoint r10{"r", "r=10", Method::kAdaptive, 4e5, nullptr};
  // 1 s of frames shown: cost = sampling / 2 virtual seconds + 0.5.
  std::vector<SweepResult> results = {
      sweep_result(defaults, runs({10.0, 12.0, 11.0}, 2.0), 1.0),
      sweep_result(b1, runs({11.5, 13.0, 14.0}, 1.0), 1.0),  // overlaps the defaults
      sweep_result(r0, runs({20.0, 21.0, 22.0}, 1.0), 1.0),  // higher beyond the spread
      sweep_result(r10, runs({8.0, 9.0, 9.5}, 4.0), 1.0),    // lower beyond the spread
  };
  const SweepResult& d = results[0];
  EXPECT_EQ(d.runs, 3);
  EXPECT_DOUBLE_EQ(d.mean_rms, 11.0);
  EXPECT_DOUBLE_EQ(d.min_rms, 10.0);
  EXPECT_DOUBLE_EQ(d.max_rms, 12.0);
  EXPECT_DOUBLE_EQ(d.cost, 1.5);
  EXPECT_DOUBLE_EQ(results[3].cost, 2.5);
  mark_pareto(&results);
  compare_with_defaults(&results);
  EXPECT_EQ(results[0].vs_default, Comparison::kWithinSpread);
  EXPECT_EQ(results[1].vs_default, Comparison::kWithinSpread);
  EXPECT_EQ(results[2].vs_default, Comparison::kHigher);
  EXPECT_EQ(results[3].vs_default, Comparison::kLower);
  // b=1 (cost 1.0, 12.8) is cheaper than the defaults (1.5, 11.0) but less accurate: both on
  // the front; r=0 is as cheap as b=1 and worse; r=10 is the most accurate.
  EXPECT_TRUE(results[0].pareto);
  EXPECT_TRUE(results[1].pareto);
  EXPECT_FALSE(results[2].pareto);
  EXPECT_TRUE(results[3].pareto);
  const std::string table = sweep_markdown(results);
  EXPECT_NE(table.find("| 11.0 (10.0-12.0) |"), std::string::npos) << table;
  EXPECT_NE(table.find("| 21.0 (20.0-22.0) | **higher** |"), std::string::npos) << table;
  EXPECT_NE(table.find("| 12.8 (11.5-14.0) | within spread |"), std::string::npos) << table;
}

// run_sweep runs a seeded point once per seed and a seedless baseline once, in parallel as in
// the table, and each point's range holds its mean.
TEST(SpreadTest, SweepRunsEverySeededPointOncePerSeed) {
  EvalConfig config = tiny_config();
  config.animations = {scene_animation("", "own", 2.0)};
  config.seeds = 3;
  config.jobs = 2;
  config.base.threads = 2;
  const std::vector<SweepPoint> points = {
      SweepPoint{"default", "defaults", Method::kAdaptive, 2e5, nullptr},
      SweepPoint{"b", "b=1", Method::kAdaptive, 2e5, [](RunSettings* s) { s->sampler.b = 1; }},
      SweepPoint{"framed 60 Hz", "200K", Method::kFramed60, 2e5, nullptr}};
  const std::vector<SweepResult> results = run_sweep(config, points);
  ASSERT_EQ(results.size(), 3u);
  EXPECT_EQ(results[0].runs, 3);
  EXPECT_EQ(results[1].runs, 3);
  EXPECT_EQ(results[2].runs, 1);
  EXPECT_LT(results[0].min_rms, results[0].max_rms) << "the seeds changed nothing";
  for (const SweepResult& r : results) {
    EXPECT_EQ(r.animation, "builtin");
    EXPECT_LE(r.min_rms, r.mean_rms);
    EXPECT_LE(r.mean_rms, r.max_rms);
    EXPECT_GT(r.cost, 0.0);
  }
  EXPECT_DOUBLE_EQ(results[2].min_rms, results[2].max_rms);
}

}  // namespace
}  // namespace afr::eval
