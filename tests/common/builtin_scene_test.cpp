#include <afr/common/builtin_scene.h>

#include <gtest/gtest.h>

namespace afr {
namespace {

TEST(BuiltinSceneTest, LoopsEveryTenSeconds) {
  const Scene s = make_builtin_scene();
  EXPECT_DOUBLE_EQ(s.duration(), kBuiltinSceneLoopSeconds);
  const SceneState a = s.evaluate(0.0), b = s.evaluate(kBuiltinSceneLoopSeconds);
  for (size_t i = 0; i < s.nodes.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) EXPECT_NEAR(a.world[i][c][r], b.world[i][c][r], 1e-9);
    }
  }
}

TEST(BuiltinSceneTest, HasWhatTheSamplerIsJudgedOn) {
  const Scene s = make_builtin_scene();
  EXPECT_TRUE(s.has_moving_geometry());
  ASSERT_NE(s.camera_node(), -1);
  EXPECT_TRUE(s.node_moves(s.camera_node()));
  bool mirror = false, textured = false, emissive = false;
  for (const Material& m : s.materials) {
    mirror |= m.metallic == 1.0f && m.roughness < 0.05f;
    textured |= m.base_color_texture != -1;
    emissive |= m.emissive != glm::vec3(0.0f);
  }
  EXPECT_TRUE(mirror);
  EXPECT_TRUE(textured);
  EXPECT_TRUE(emissive);
  EXPECT_GE(s.lights.size(), 1u);
}

TEST(BuiltinSceneTest, CameraMovesAndKeepsTheRoomInView) {
  const Scene s = make_builtin_scene();
  const Camera c0 = s.camera_at(s.evaluate(0.0));
  const Camera c1 = s.camera_at(s.evaluate(2.5));
  EXPECT_GT(glm::length(c0.eye - c1.eye), 1.0);
  for (double t = 0.0; t < 10.0; t += 0.5) {
    const Camera c = s.camera_at(s.evaluate(t));
    glm::dvec2 xy;
    // The room's center stays near the middle of the image.
    ASSERT_TRUE(c.project({0.0, 0.8, 0.0}, 100, 100, &xy, nullptr));
    EXPECT_NEAR(xy.x, 50.0, 5.0) << "t=" << t;
    EXPECT_NEAR(xy.y, 50.0, 5.0) << "t=" << t;
  }
}

}  // namespace
}  // namespace afr
