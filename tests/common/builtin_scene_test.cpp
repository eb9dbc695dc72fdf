#include <afr/common/builtin_scene.h>

#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

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

// The payload that stands for the scene on the wire: its first line alone, or with the ray
// depth; anything else after the first line, or a depth out of range, is refused by name.
TEST(BuiltinScenePayloadTest, CarriesTheRayDepthAndRefusesAnythingElse) {
  const auto bytes = [](const std::string& text) {
    return std::vector<uint8_t>(text.begin(), text.end());
  };
  EXPECT_EQ(builtin_scene_payload(), "afr builtin scene v1\n");
  EXPECT_EQ(builtin_scene_payload(7), "afr builtin scene v1\nray depth 7\n");
  for (const std::optional<int> depth :
       {std::optional<int>(), std::optional<int>(0), std::optional<int>(kMaxRayDepth)}) {
    const std::vector<uint8_t> payload = bytes(builtin_scene_payload(depth));
    EXPECT_TRUE(is_builtin_scene_payload(payload));
    EXPECT_EQ(builtin_scene_from_payload(payload).ray_depth, depth);
  }
  EXPECT_FALSE(is_builtin_scene_payload(bytes("afr builtin scene v2\n")));
  EXPECT_FALSE(is_builtin_scene_payload(bytes("{\"asset\": {\"version\": \"2.0\"}}")));
  EXPECT_FALSE(is_builtin_scene_payload({}));
  const auto refusal = [&](const std::string& text) {
    try {
      builtin_scene_from_payload(bytes(text));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string binary("afr builtin scene v1\n\0\xff", 23);
  for (const std::string& text : std::vector<std::string>{
           "afr builtin scene v1\nray depth 3", "afr builtin scene v1\nray depth 3\n\n",
           "afr builtin scene v1\nray depth three\n", "afr builtin scene v1\nray depth \n",
           "afr builtin scene v1\nray depth 99999999999999999999\n",
           "afr builtin scene v1\nfog 1\n", binary}) {
    SCOPED_TRACE(text);
    EXPECT_NE(refusal(text).find("after its first line"), std::string::npos) << refusal(text);
  }
  EXPECT_NE(refusal("afr builtin scene v1\nray depth 11\n").find("ray depth 11 (0 to 10)"),
            std::string::npos);
  EXPECT_NE(refusal("afr builtin scene v1\nray depth -1\n").find("ray depth -1 (0 to 10)"),
            std::string::npos);
  EXPECT_NE(refusal("not it").find("does not start with"), std::string::npos);
}

}  // namespace
}  // namespace afr
