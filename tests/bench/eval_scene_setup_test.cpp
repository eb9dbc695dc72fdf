// Camera paths in place of a scene's camera, and the presets that sampler_node and
// display_node accept.
#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>
#include <afr/common/presets.h>
#include <afr/display/filter.h>
#include <afr/eval/scene_setup.h>
#include <afr/sampler/sampler_config.h>

#include <gtest/gtest.h>

#include <random>

namespace afr::eval {
namespace {

TEST(SceneSetupTest, SceneCameraFollowsTheCameraPath) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<CameraKey> keys;
  for (int i = 0; i < 20; ++i) {
    CameraKey k;
    k.time = 0.3 * i;
    k.eye = glm::dvec3(u(rng), 1.0 + u(rng), 4.0 + u(rng));
    k.rotation = glm::normalize(glm::dquat(2.0 + u(rng), u(rng), u(rng), u(rng)));
    k.yfov = 0.9;
    keys.push_back(k);
  }
  const CameraPath path(keys);
  Scene scene = make_builtin_scene();
  apply_camera_path(path, &scene);
  for (int i = 0; i < 200; ++i) {
    const double t = -0.5 + 7.0 * (i / 200.0);
    const Camera a = scene.camera_at(scene.evaluate(t));
    const Camera b = path.camera(t);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(a.eye[c], b.eye[c], 1e-9) << t;
      EXPECT_NEAR(a.forward[c], b.forward[c], 1e-9) << t;
      EXPECT_NEAR(a.up[c], b.up[c], 1e-9) << t;
    }
    EXPECT_DOUBLE_EQ(a.yfov, 0.9);
  }
}

TEST(SceneSetupTest, APathThatZoomsAnimatesTheCamerasFieldOfView) {
  for (bool orthographic : {false, true}) {
    CameraKey a, b, c;
    b.time = 1.0;
    b.yfov = a.yfov * 1.5;
    c.time = 3.0;
    c.yfov = a.yfov;
    if (orthographic) a.ymag = 1.0, b.ymag = 2.0, c.ymag = 4.0;
    const CameraPath path({a, b, c});
    Scene scene = make_builtin_scene();
    apply_camera_path(path, &scene);
    EXPECT_EQ(scene.property_channels.size(), orthographic ? 2u : 1u);
    for (double t : {-1.0, 0.0, 0.25, 1.0, 2.0, 2.9, 3.0, 5.0}) {
      const Camera got = scene.camera_at(scene.evaluate(t)), want = path.camera(t);
      EXPECT_NEAR(got.yfov, want.yfov, 1e-9) << t;
      EXPECT_NEAR(got.ymag, want.ymag, 1e-9) << t;
      EXPECT_EQ(got.orthographic(), orthographic);
    }
  }
}

TEST(PresetsTest, NamedPresetsSetTheirKnobsAndValidate) {
  ASSERT_EQ(presets().size(), 3u);
  for (const char* name : {"fast", "balanced", "accurate"}) {
    const Preset& p = find_preset(name);
    SamplerConfig c;
    apply_preset(p, &c);
    EXPECT_EQ(c.b, p.b);
    EXPECT_EQ(c.r, p.r);
    EXPECT_EQ(c.chunk, p.chunk);
    EXPECT_EQ(c.min_tiles, p.min_tiles);
    EXPECT_EQ(c.max_tiles, p.max_tiles);
    EXPECT_NO_THROW(c.validate()) << name;
    EXPECT_GE(p.reconstruction.samples_per_pixel, 1.0);
    EXPECT_LT(p.reconstruction.min_spatial_extent, p.reconstruction.max_spatial_extent);
  }
  // Balanced is afr's defaults.
  SamplerConfig defaults, balanced;
  apply_preset(find_preset("balanced"), &balanced);
  EXPECT_EQ(balanced.b, defaults.b);
  EXPECT_EQ(balanced.r, defaults.r);
  EXPECT_EQ(balanced.chunk, defaults.chunk);
  const FilterLimits limits;
  const ReconstructionPreset& recon = find_preset("balanced").reconstruction;
  EXPECT_EQ(recon.min_spatial_extent, limits.min_spatial_extent);
  EXPECT_EQ(recon.max_spatial_extent, limits.max_spatial_extent);
  EXPECT_EQ(recon.max_temporal_extent, limits.max_temporal_extent);
  try {
    find_preset("fastest");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "unknown preset 'fastest' (expected fast, balanced, accurate)");
  }
}

}  // namespace
}  // namespace afr::eval
