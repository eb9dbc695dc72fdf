// The glTF loader's tests of nodes, instancing, visibility, cameras and lights.
#include "gltf_loader_test.h"

namespace afr {
namespace {

using namespace gltf_test;

// EXT_mesh_gpu_instancing: a node's mesh is drawn once per instance, each instance's TRS (its
// rotation here as normalized shorts) applied before the node's own: instance k becomes node
// (the file's node count + k), a child of the node carrying its mesh, and the node keeps none.
// Attributes of different counts, or a node without a mesh, fail naming the node.
TEST_F(GltfLoaderTest, GpuInstancingDrawsTheMeshOncePerInstance) {
  GltfBuilder b;
  add_quad(&b);
  const int t = b.add_floats({0, 0, 0, 5, 0, 0, 0, 5, 0}, 3);
  const std::vector<int16_t> r = {0, 0, 0, 32767, 0, 0, 32767, 0, 0, 0, 0, 32767};
  const int rot = b.add_accessor(b.add_view(r), kShort, "VEC4", 3, 0, /*normalized=*/true);
  const int scale = b.add_floats({1, 1, 1, 2, 2, 2, 1, 1, 1}, 3);
  b.doc()["nodes"][0]["translation"] = {0, 0, -10};
  b.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {
      {"TRANSLATION", t}, {"ROTATION", rot}, {"SCALE", scale}};
  b.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  b.doc()["extensionsRequired"] = {"EXT_mesh_gpu_instancing"};
  b.write_glb(dir_ / "instanced.glb");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "instanced.glb", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.nodes[0].mesh, -1);
  EXPECT_EQ(scene.nodes[0].children, (std::vector<int>{1, 2, 3}));
  const SceneState state = scene.evaluate(0.0);
  // The quad's corner (1, 0, 0): as it is, turned half round z and doubled, raised.
  const glm::dvec3 want[3] = {{1, 0, -10}, {3, 0, -10}, {1, 5, -10}};
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(scene.nodes[1 + k].mesh, 0);
    EXPECT_EQ(scene.nodes[1 + k].parent, 0);
    const glm::dvec3 corner = glm::dvec3(state.world[1 + k] * glm::dvec4(1, 0, 0, 1));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(corner[c], want[k][c], 1e-4) << "instance " << k;
  }

  GltfBuilder short_scale = b;
  short_scale.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["SCALE"] =
      short_scale.add_floats({1, 1, 1, 2, 2, 2}, 3);
  short_scale.write_embedded(dir_ / "counts.gltf");
  expect_error(dir_ / "counts.gltf",
               "node 0 EXT_mesh_gpu_instancing has 2 instances in SCALE but 3 in another "
               "attribute");
  GltfBuilder no_mesh = b;
  no_mesh.doc()["nodes"].push_back(
      {{"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}});
  no_mesh.doc()["nodes"][0]["children"] = {1};
  no_mesh.write_embedded(dir_ / "no_mesh.gltf");
  expect_error(dir_ / "no_mesh.gltf", "node 1 EXT_mesh_gpu_instancing: the node has no mesh");
  GltfBuilder none = b;
  none.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"_ID", t}};
  none.write_embedded(dir_ / "none.gltf");
  expect_error(dir_ / "none.gltf",
               "node 0 EXT_mesh_gpu_instancing has none of TRANSLATION, ROTATION and SCALE");
}

// CESIUM_RTC (3D Tiles' batched models, here required as such files require it): the scene is
// drawn relative to its center, which the log names: nodes keep their own transforms, so a
// center far out on the Earth costs no precision. A center that is not 3 finite numbers fails.
TEST_F(GltfLoaderTest, RtcCenterIsNamedAndTheSceneDrawnRelativeToIt) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"][0]["translation"] = {0, 0, -3};
  b.doc()["extensions"]["CESIUM_RTC"]["center"] = {1215012.5, -4736313.0, 4081605.25};
  b.doc()["extensionsUsed"] = {"CESIUM_RTC"};
  b.doc()["extensionsRequired"] = {"CESIUM_RTC"};
  b.write_glb(dir_ / "rtc.glb");
  testing::LogCapture log;
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "rtc.glb", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_EQ(log.lines_with("CESIUM_RTC: drawn relative to its center (1215012.5, -4736313, "
                           "4081605.25)")
                .size(),
            1u);
  const glm::dvec3 corner = glm::dvec3(scene.evaluate(0.0).world[0] * glm::dvec4(1, 0, 0, 1));
  EXPECT_EQ(corner, glm::dvec3(1, 0, -3));

  for (const json& center : {json::array({1, 2}), json::array({1, 2, "3"}), json(7)}) {
    GltfBuilder bad = b;
    bad.doc()["extensions"]["CESIUM_RTC"]["center"] = center;
    bad.write_embedded(dir_ / "bad_rtc.gltf");
    expect_error(dir_ / "bad_rtc.gltf",
                 "CESIUM_RTC: \"center\" must be an array of 3 finite numbers");
  }
}

// KHR_node_visibility: a node whose `visible` is false hides its own and its descendants'
// meshes and lights (a child's own `true` does not show it again); cameras stay, and an
// animation of a hidden mesh's morph weights is dropped with it. A `visible` that is not a
// boolean fails naming the node.
TEST_F(GltfLoaderTest, NodeVisibilityHidesTheMeshesAndLightsBelowAHiddenNode) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = {{{"POSITION", positions}}};
  b.doc()["meshes"][0]["weights"] = {0.0};
  const json hidden = {{"KHR_node_visibility", {{"visible", false}}}};
  const json shown = {{"KHR_node_visibility", {{"visible", true}}}};
  b.doc()["nodes"] = json::array(
      {{{"mesh", 0}, {"children", {1}}, {"extensions", hidden}},
       {{"mesh", 0},
        {"camera", 0},
        {"extensions",
         {{"KHR_node_visibility", {{"visible", true}}}, {"KHR_lights_punctual", {{"light", 0}}}}}},
       {{"mesh", 0}},
       {{"mesh", 0}, {"extensions", shown}, {"translation", {0, 0, 1}}}});
  b.doc()["scenes"][0]["nodes"] = {0, 2, 3};
  b.doc()["cameras"] = {
      {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}}};
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}}};
  b.doc()["extensionsUsed"] = {"KHR_node_visibility", "KHR_lights_punctual"};
  b.doc()["extensionsRequired"] = {"KHR_node_visibility"};
  const int times = b.add_floats({0, 1}, 1);
  const int weights = b.add_floats({0, 1}, 1);
  b.doc()["animations"] = {
      {{"channels", {{{"sampler", 0}, {"target", {{"node", 1}, {"path", "weights"}}}}}},
       {"samplers", {{{"input", times}, {"output", weights}}}}}};
  const fs::path path = dir_ / "visibility.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.nodes[0].mesh, -1);
  EXPECT_EQ(scene.nodes[1].mesh, -1);  // its own `true` does not show it below a hidden node
  EXPECT_EQ(scene.nodes[1].light, -1);
  EXPECT_EQ(scene.nodes[1].camera, 0);
  EXPECT_EQ(scene.nodes[2].mesh, 0);
  EXPECT_EQ(scene.nodes[3].mesh, 0);
  EXPECT_EQ(scene.triangle_count(), 4u);
  EXPECT_EQ(scene.camera_node(), 1);
  EXPECT_TRUE(scene.channels.empty());

  b.doc()["nodes"][0]["extensions"]["KHR_node_visibility"]["visible"] = "no";
  b.write_embedded(path);
  expect_error(path, "node 0 KHR_node_visibility has an invalid visible (true or false)");
}

// EXT_mesh_gpu_instancing where afr does not follow it: an animation of an instanced node's
// morph weights warns and is skipped (the instances keep the weights they load with); on a
// skinned node the extension warns and the mesh is drawn once, where its joints put it.
TEST_F(GltfLoaderTest, GpuInstancingOfWeightAnimatedOrSkinnedNodesWarns) {
  GltfBuilder b;
  add_quad(&b);
  const int up = b.add_floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, 3);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = json::array({{{"POSITION", up}}});
  b.doc()["meshes"][0]["weights"] = {0.5};
  const int t = b.add_floats({0, 0, 0, 2, 0, 0}, 3);
  b.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", t}};
  b.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  const int times = b.add_floats({0, 1}, 1);
  const int weights = b.add_floats({0, 1}, 1);
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}},
        {"samplers", {{{"input", times}, {"output", weights}}}}}});
  b.write_embedded(dir_ / "weights.gltf");
  GltfLoadReport report;
  const Scene morphed = load_gltf(dir_ / "weights.gltf", &report);
  EXPECT_EQ(count_containing(report.warnings,
                             "animated morph weights of a node with "
                             "EXT_mesh_gpu_instancing are not supported"),
            1u);
  EXPECT_TRUE(morphed.channels.empty());
  ASSERT_EQ(morphed.nodes.size(), 3u);
  EXPECT_EQ(morphed.nodes[1].mesh, 0);
  EXPECT_EQ(morphed.nodes[2].mesh, 0);

  GltfBuilder k;
  add_quad(&k);
  const int joints =
      k.add_accessor(k.add_view(std::vector<uint8_t>(16, 0)), kUnsignedByte, "VEC4", 4);
  const int joint_weights = k.add_floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, 4);
  k.doc()["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = joints;
  k.doc()["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] = joint_weights;
  k.doc()["nodes"] = json::array(
      {{{"mesh", 0},
        {"skin", 0},
        {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}},
       {{"translation", {0, 0, -5}}}});
  k.doc()["skins"] = json::array({{{"joints", {1}}}});
  k.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
  k.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  k.write_embedded(dir_ / "skinned.gltf");
  report = {};
  const Scene skinned = load_gltf(dir_ / "skinned.gltf", &report);
  EXPECT_EQ(count_containing(report.warnings,
                             "EXT_mesh_gpu_instancing on a node with a skin is not supported"),
            1u);
  ASSERT_EQ(skinned.nodes.size(), 2u);
  EXPECT_EQ(skinned.nodes[0].mesh, 0);
  EXPECT_EQ(skinned.nodes[0].skin, 0);
}

TEST_F(GltfLoaderTest, NodeHierarchyWorldTransformsMatchHandComputedMatrices) {
  GltfBuilder b;
  add_quad(&b);
  const double h = std::sqrt(0.5);
  b.doc()["nodes"] = json::array({// Translation (1, 2, 3), 90 degrees about +z, uniform scale 2.
                                  {{"name", "parent"},
                                   {"children", {1}},
                                   {"translation", {1, 2, 3}},
                                   {"rotation", {0, 0, h, h}},
                                   {"scale", {2, 2, 2}}},
                                  // A translation by (0, 1, 0) given as a column-major matrix.
                                  {{"name", "child"},
                                   {"children", {2}},
                                   {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 1}}},
                                  {{"name", "grandchild"}, {"translation", {0, 0, 5}}, {"mesh", 0}},
                                  {{"name", "other root"}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 3}}}});
  const fs::path path = dir_ / "hierarchy.gltf";
  b.write_embedded(path);

  const Scene scene = load_gltf(path);
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.roots, (std::vector<int>{0, 3}));
  EXPECT_EQ(scene.nodes[1].parent, 0);
  EXPECT_EQ(scene.nodes[2].parent, 1);
  EXPECT_EQ(scene.nodes[2].mesh, 0);
  EXPECT_TRUE(scene.nodes[1].matrix.has_value());
  EXPECT_FALSE(scene.is_animated());

  // By hand: R S maps x to (0, 2, 0), y to (-2, 0, 0), z to (0, 0, 2). The child's origin
  // (0, 1, 0) goes to (-2, 0, 0) + (1, 2, 3) = (-1, 2, 3); the grandchild's (0, 0, 5) on top of
  // that adds (0, 0, 10).
  const glm::dmat4 parent(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1);
  const glm::dmat4 child(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, -1, 2, 3, 1);
  const glm::dmat4 grandchild(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, -1, 2, 13, 1);
  const SceneState state = scene.evaluate(0.0);
  ASSERT_EQ(state.world.size(), 4u);
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      EXPECT_NEAR(state.world[0][c][r], parent[c][r], 1e-12) << c << "," << r;
      EXPECT_NEAR(state.world[1][c][r], child[c][r], 1e-12) << c << "," << r;
      EXPECT_NEAR(state.world[2][c][r], grandchild[c][r], 1e-12) << c << "," << r;
      EXPECT_EQ(state.world[3][c][r], c == r ? 1.0 : 0.0);
    }
  }
}

TEST_F(GltfLoaderTest, CameraAndAllThreeLightTypesLoadWithExtras) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
  b.doc()["cameras"] = json::array(
      {{{"name", "eye"},
        {"type", "perspective"},
        {"perspective", {{"yfov", 0.6}, {"znear", 0.05}, {"zfar", 100}, {"aspectRatio", 1.5}}}}});
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = json::array(
      {{{"name", "bulb"},
        {"type", "point"},
        {"color", {1.0, 0.5, 0.25}},
        {"intensity", 3.0},
        {"range", 10.0},
        {"extras", {{"afr_falloff", "none"}}}},
       {{"type", "directional"}, {"intensity", 2.0}},
       {{"type", "spot"}, {"spot", {{"innerConeAngle", 0.25}, {"outerConeAngle", 0.5}}}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}},
                                  {{"name", "camera"}, {"camera", 0}, {"translation", {0, 1, 5}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 2}}}}}}});
  b.doc()["scenes"] = json::array(
      {{{"nodes", {0, 1, 2, 3, 4}},
        {"extras", {{"afr_background", {0.1, 0.2, 0.3}}, {"afr_ambient", {0.05, 0.04, 0.03}}}}}});
  const fs::path path = dir_ / "lit.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty());
  ASSERT_EQ(scene.cameras.size(), 1u);
  EXPECT_EQ(scene.cameras[0].name, "eye");
  EXPECT_DOUBLE_EQ(scene.cameras[0].yfov, 0.6);
  EXPECT_DOUBLE_EQ(scene.cameras[0].znear, 0.05);
  EXPECT_DOUBLE_EQ(scene.cameras[0].aspect_ratio, 1.5);
  EXPECT_EQ(scene.nodes[1].camera, 0);
  EXPECT_EQ(scene.camera_node(), 1);
  EXPECT_DOUBLE_EQ(scene.camera_aspect_ratio(), 1.5);
  const Camera camera = scene.camera_at(scene.evaluate(0.0));
  EXPECT_NEAR(glm::length(camera.eye - glm::dvec3(0, 1, 5)), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(camera.yfov, 0.6);

  ASSERT_EQ(scene.lights.size(), 3u);
  const Light& point = scene.lights[0];
  EXPECT_EQ(point.name, "bulb");
  EXPECT_EQ(point.type, Light::Type::kPoint);
  EXPECT_EQ(point.color, glm::vec3(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(point.intensity, 3.0f);
  EXPECT_EQ(point.range, 10.0f);
  EXPECT_FALSE(point.inverse_square_falloff);
  const Light& directional = scene.lights[1];
  EXPECT_EQ(directional.type, Light::Type::kDirectional);
  EXPECT_EQ(directional.intensity, 2.0f);
  EXPECT_EQ(directional.color, glm::vec3(1.0f));
  EXPECT_EQ(directional.range, 0.0f);
  EXPECT_TRUE(directional.inverse_square_falloff);
  const Light& spot = scene.lights[2];
  EXPECT_EQ(spot.type, Light::Type::kSpot);
  EXPECT_EQ(spot.inner_cone_angle, 0.25f);
  EXPECT_EQ(spot.outer_cone_angle, 0.5f);
  EXPECT_TRUE(spot.inverse_square_falloff);
  EXPECT_EQ(scene.nodes[2].light, 0);
  EXPECT_EQ(scene.nodes[3].light, 1);
  EXPECT_EQ(scene.nodes[4].light, 2);
  EXPECT_EQ(scene.nodes[0].light, -1);

  EXPECT_EQ(scene.background, glm::vec3(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(scene.ambient, glm::vec3(0.05f, 0.04f, 0.03f));
}

// Lights whose color has a component below 0 (the extension's minimum), or whose intensity
// times its color is beyond a float (the tracer's radiance would be infinite and every sample
// it lights NaN), are refused by name.
TEST_F(GltfLoaderTest, LightsOfNegativeColorOrOfAnIntensityBeyondAFloatAreRefused) {
  const auto lit = [&](const json& light, const std::string& name) {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
    b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = json::array({light});
    b.doc()["nodes"] =
        json::array({{{"mesh", 0}}, {{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}}});
    b.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
    const fs::path path = dir_ / name;
    b.write_embedded(path);
    return path;
  };
  expect_error(lit({{"type", "point"}, {"color", {1.0, -0.5, 1.0}}}, "negative.gltf"),
               "has an invalid color (three finite numbers, none below 0)");
  expect_error(lit({{"type", "point"}, {"intensity", 1e39}}, "huge.gltf"),
               "has an intensity 1e+39 that, times its color, is beyond a float's range");
  expect_error(lit({{"type", "spot"},
                    {"spot", json::object()},
                    {"intensity", 3e38},
                    {"color", {2.0, 1.0, 1.0}}},
                   "huge_times_color.gltf"),
               "beyond a float's range");
  // The largest that fits loads.
  EXPECT_NO_THROW(load_gltf(lit({{"type", "directional"}, {"intensity", 3e38}}, "large.gltf")));
}

// A camera's aspect ratio as the file gives it (CameraModel::aspect_ratio): a perspective
// camera's aspectRatio, where it has one that glTF allows, and an orthographic camera's
// xmag / ymag (magnitudes); the active camera's is the scene's.
TEST_F(GltfLoaderTest, CamerasKeepTheAspectRatioTheFileGives) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["cameras"] = json::array(
      {{{"type", "perspective"}, {"perspective", {{"yfov", 0.6}, {"znear", 0.05}}}},
       {{"type", "perspective"},
        {"perspective", {{"yfov", 0.6}, {"znear", 0.05}, {"aspectRatio", -2.0}}}},
       {{"type", "orthographic"},
        {"orthographic", {{"xmag", -3.0}, {"ymag", 1.5}, {"znear", 0.0}, {"zfar", 10.0}}}},
       {{"type", "perspective"},
        {"perspective", {{"yfov", 0.6}, {"znear", 0.05}, {"aspectRatio", 1.7778}}}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}}});
  for (int c = 0; c < 4; ++c) b.doc()["nodes"].push_back({{"camera", c}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 3, 1, 2, 4}}}});
  const fs::path path = dir_ / "cameras.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.cameras.size(), 4u);
  EXPECT_EQ(scene.cameras[0].aspect_ratio, 0.0);  // none given
  EXPECT_EQ(scene.cameras[1].aspect_ratio, 0.0);  // not > 0: not used, with a warning
  EXPECT_DOUBLE_EQ(scene.cameras[2].aspect_ratio, 2.0);
  EXPECT_DOUBLE_EQ(scene.cameras[3].aspect_ratio, 1.7778);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("aspectRatio of -2"), std::string::npos) << report.warnings[0];
  EXPECT_EQ(scene.camera_node(), 3);  // the first camera node in scene order: the orthographic
  EXPECT_DOUBLE_EQ(scene.camera_aspect_ratio(), 2.0);
}

// glTF requires a scene's nodes to be distinct roots; UniGLTF lists a child whose parent is
// outside the scene, which is drawn as a root with its own transform, as viewers draw it. A
// node listed with its ancestor, or twice, is drawn once.
TEST_F(GltfLoaderTest, SceneNodesThatAreNotRootsAreDrawnOnceWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] =
      json::array({{{"name", "tmpParent"}, {"children", {1}}, {"translation", {5, 0, 0}}},
                   {{"mesh", 0}, {"translation", {0, 2, 0}}, {"children", {2}}},
                   {{"mesh", 0}, {"translation", {0, 0, 3}}}});
  b.doc()["scenes"] = json::array({{{"nodes", {1}}}});
  const fs::path path = dir_ / "unigltf.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  Scene scene = load_gltf(path, &report);
  EXPECT_EQ(scene.roots, (std::vector<int>{1}));
  SceneState state = scene.evaluate(0.0);
  EXPECT_EQ(glm::dvec3(state.world[1][3]), glm::dvec3(0, 2, 0));
  EXPECT_EQ(glm::dvec3(state.world[2][3]), glm::dvec3(0, 2, 3));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("scene 0 lists node 1, a child of node 0, which is not in the "
                                    "scene; glTF requires a scene's nodes to be roots: it is drawn "
                                    "as one, without its parents' transforms"),
            std::string::npos)
      << report.warnings[0];

  b.doc()["scenes"] = json::array({{{"nodes", {2, 0, 0}}}});
  b.write_embedded(path);
  report = {};
  scene = load_gltf(path, &report);
  EXPECT_EQ(scene.roots, (std::vector<int>{0}));
  state = scene.evaluate(0.0);
  EXPECT_EQ(glm::dvec3(state.world[2][3]), glm::dvec3(5, 2, 3));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("scene 0 lists node 2 and its ancestor node 0, which glTF "
                                    "forbids: it is drawn once"),
            std::string::npos)
      << report.warnings[0];
}

TEST_F(GltfLoaderTest, CycleInTheNodeGraphFails) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] = json::array({{{"mesh", 0}}, {{"children", {2}}}, {{"children", {1}}}});
  const fs::path path = dir_ / "cycle.gltf";
  b.write_embedded(path);
  expect_error(path, "cycle");
}

}  // namespace
}  // namespace afr
