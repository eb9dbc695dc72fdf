// The glTF loader's tests of animations: channels and KHR_animation_pointer.
#include "gltf_loader_test.h"
#include "support/png.h"

namespace afr {
namespace {

using namespace gltf_test;

TEST_F(GltfLoaderTest, AnimationChannelsLoadWithTheirInterpolationAndValues) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] =
      json::array({{{"mesh", 0}, {"children", {1, 2}}}, json::object(), json::object()});
  const int linear_times = b.add_floats({0.0f, 0.5f, 1.25f}, 1);
  const int translations = b.add_floats({0, 0, 0, 1, 2, 3, 4, 5, 6}, 3);
  const int step_times = b.add_floats({0.0f, 1.0f}, 1);
  // Rotations as normalized shorts: (0, 0, 0, 1) and (0, 0, 1, 0).
  const std::vector<int16_t> rotation_shorts = {0, 0, 0, 32767, 0, 0, 32767, 0};
  const int rotations =
      b.add_accessor(b.add_view(rotation_shorts), kShort, "VEC4", 2, 0, /*normalized=*/true);
  const int cubic_times = b.add_floats({0.0f, 2.0f}, 1);
  // In-tangent, value, out-tangent per key.
  const int cubic_scales = b.add_floats({0, 0, 0, 1, 1, 1, 1, 0, 0,  //
                                         0, 1, 0, 2, 3, 4, 0, 0, 0},
                                        3);
  b.doc()["animations"] = json::array(
      {{{"channels",
         {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
          {{"sampler", 1}, {"target", {{"node", 1}, {"path", "rotation"}}}}}},
        {"samplers",
         {{{"input", linear_times}, {"output", translations}},  // LINEAR is the default
          {{"input", step_times}, {"output", rotations}, {"interpolation", "STEP"}}}}},
       {{"channels", {{{"sampler", 0}, {"target", {{"node", 2}, {"path", "scale"}}}}}},
        {"samplers",
         {{{"input", cubic_times}, {"output", cubic_scales}, {"interpolation", "CUBICSPLINE"}}}}}});
  const fs::path path = dir_ / "animated.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_TRUE(scene.is_animated());
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);
  ASSERT_EQ(scene.channels.size(), 3u);

  const AnimationChannel& t = scene.channels[0];
  EXPECT_EQ(t.node, 0);
  EXPECT_EQ(t.path, AnimatedPath::kTranslation);
  EXPECT_EQ(t.interpolation, Interpolation::kLinear);
  EXPECT_EQ(t.times, (std::vector<double>{0.0, 0.5, 1.25}));
  ASSERT_EQ(t.values.size(), 3u);
  EXPECT_EQ(glm::dvec3(t.values[1]), glm::dvec3(1, 2, 3));
  EXPECT_EQ(glm::dvec3(t.values[2]), glm::dvec3(4, 5, 6));

  const AnimationChannel& r = scene.channels[1];
  EXPECT_EQ(r.node, 1);
  EXPECT_EQ(r.path, AnimatedPath::kRotation);
  EXPECT_EQ(r.interpolation, Interpolation::kStep);
  EXPECT_EQ(r.times, (std::vector<double>{0.0, 1.0}));
  ASSERT_EQ(r.values.size(), 2u);
  EXPECT_EQ(r.values[0], glm::dvec4(0, 0, 0, 1));  // (x, y, z, w)
  EXPECT_EQ(r.values[1], glm::dvec4(0, 0, 1, 0));

  const AnimationChannel& s = scene.channels[2];
  EXPECT_EQ(s.node, 2);
  EXPECT_EQ(s.path, AnimatedPath::kScale);
  EXPECT_EQ(s.interpolation, Interpolation::kCubicSpline);
  EXPECT_EQ(s.times, (std::vector<double>{0.0, 2.0}));
  ASSERT_EQ(s.values.size(), 6u);
  EXPECT_EQ(glm::dvec3(s.values[1]), glm::dvec3(1, 1, 1));
  EXPECT_EQ(glm::dvec3(s.values[2]), glm::dvec3(1, 0, 0));
  EXPECT_EQ(glm::dvec3(s.values[3]), glm::dvec3(0, 1, 0));
  EXPECT_EQ(glm::dvec3(s.values[4]), glm::dvec3(2, 3, 4));
}

// KHR_animation_pointer: channels whose pointer names a node's translation, rotation, scale or
// morph weights animate it as a channel of that node and path would; a pointer to another
// property (here a factor of ADOBE_materials_thin_transparency, which afr does not read) warns
// once per kind and is skipped; a pointer to a node the file lacks, or a channel without a pointer,
// fails naming the channel.
TEST_F(GltfLoaderTest, AnimationPointersToANodesTransformAreAnimated) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["materials"] = json::array({json::object(), json::object()});
  const int times = b.add_floats({0, 2}, 1);
  const int moves = b.add_floats({0, 0, 0, 4, 0, 0}, 3);
  const int colors = b.add_floats({1, 0, 0, 1, 0, 0, 1, 1}, 4);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(1,
                         "/materials/0/extensions/ADOBE_materials_thin_transparency/"
                         "transmissionFactor"),
         pointer_channel(0, "/nodes/0/translation"),
         pointer_channel(1,
                         "/materials/1/extensions/ADOBE_materials_thin_transparency/"
                         "transmissionFactor")}},
       {"samplers",
        {{{"input", times}, {"output", moves}}, {{"input", times}, {"output", colors}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "pointer.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].node, 0);
  EXPECT_EQ(scene.channels[0].path, AnimatedPath::kTranslation);
  EXPECT_NEAR(scene.evaluate(1.0).world[0][3].x, 2.0, 1e-9);  // halfway to x = 4
  ASSERT_EQ(report.warnings.size(), 1u) << report.warnings.back();
  EXPECT_NE(report.warnings[0].find("KHR_animation_pointer animations of "
                                    "/materials/#/extensions/ADOBE_materials_thin_transparency/"
                                    "transmissionFactor are not supported"),
            std::string::npos)
      << report.warnings[0];
  EXPECT_TRUE(scene.property_channels.empty());

  b.doc()["animations"][0]["channels"][1] = pointer_channel(0, "/nodes/7/translation");
  b.write_embedded(path);
  expect_error(path,
               "animation 0 channel 1 KHR_animation_pointer \"/nodes/7/translation\" "
               "targets node 7, but there are 1");
  b.doc()["animations"][0]["channels"][1]["target"].erase("extensions");
  b.write_embedded(path);
  expect_error(path, "animation 0 channel 1 KHR_animation_pointer has no \"pointer\" string");
}

// A pointer to a mesh's weights animates the morph weights of every node that shows the mesh
// with the mesh's own weights (a node with weights of its own keeps them, as glTF has it).
TEST_F(GltfLoaderTest, AnimationPointersToAMeshsWeightsAnimateTheNodesShowingIt) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = {
      {{"POSITION", b.add_floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, 3)}}};
  b.doc()["meshes"][0]["weights"] = {0};
  b.doc()["nodes"].push_back({{"mesh", 0}, {"weights", {0.5}}});
  b.doc()["nodes"].push_back({{"mesh", 0}, {"translation", {3, 0, 0}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1, 2};
  b.doc()["animations"] = {
      {{"channels", {pointer_channel(0, "/meshes/0/weights")}},
       {"samplers", {{{"input", b.add_floats({0, 1}, 1)}, {"output", b.add_floats({0, 1}, 1)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "mesh_weights.gltf";
  b.write_embedded(path);
  const Scene scene = load_gltf(path);
  ASSERT_EQ(scene.channels.size(), 2u);
  for (const AnimationChannel& c : scene.channels) {
    EXPECT_EQ(c.path, AnimatedPath::kWeights);
    EXPECT_NE(c.node, 1);  // its own weights
  }
  EXPECT_NE(scene.channels[0].node, scene.channels[1].node);

  b.doc()["animations"][0]["channels"][0] = pointer_channel(0, "/meshes/4/weights");
  b.write_embedded(path);
  expect_error(path, "\"/meshes/4/weights\" targets mesh 4, but there are 1");
}

// An orthographic camera's ymag and znear are animated through their own pointers; its near
// plane may reach 0 (glTF allows it there), its ymag may not.
TEST_F(GltfLoaderTest, AnimationPointersToAnOrthographicCameraAnimateItsView) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["cameras"] = {
      {{"type", "orthographic"},
       {"orthographic", {{"xmag", 1}, {"ymag", 2}, {"znear", 0.5}, {"zfar", 9}}}}};
  b.doc()["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1};
  const int times = b.add_floats({0, 2}, 1);
  const int ymags = b.add_floats({2, 4}, 1);
  const int nears = b.add_floats({0.5, 0}, 1);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/cameras/0/orthographic/ymag"),
         pointer_channel(1, "/cameras/0/orthographic/znear")}},
       {"samplers",
        {{{"input", times}, {"output", ymags}}, {{"input", times}, {"output", nears}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "ortho_zoom.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings[0];
  ASSERT_EQ(scene.property_channels.size(), 2u);
  const Camera half = scene.camera_at(scene.evaluate(1.0));
  EXPECT_TRUE(half.orthographic());
  EXPECT_NEAR(half.ymag, 3.0, 1e-6);
  EXPECT_NEAR(half.znear, 0.25, 1e-6);
  const Camera end = scene.camera_at(scene.evaluate(2.0));
  EXPECT_NEAR(end.ymag, 4.0, 1e-6);
  EXPECT_GT(end.znear, 0.0);  // kept just in front of the eye's plane

  GltfBuilder zero;
  add_quad(&zero);
  zero.doc()["cameras"] = b.doc()["cameras"];
  zero.doc()["nodes"].push_back({{"camera", 0}});
  zero.doc()["scenes"][0]["nodes"] = {0, 1};
  const int zero_times = zero.add_floats({0, 2}, 1);
  const int zero_ymags = zero.add_floats({2, 0}, 1);
  zero.doc()["animations"] = {{{"channels", {pointer_channel(0, "/cameras/0/orthographic/ymag")}},
                               {"samplers", {{{"input", zero_times}, {"output", zero_ymags}}}}}};
  zero.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  zero.write_embedded(path);
  expect_error(path,
               "animation 0 channel 0 (KHR_animation_pointer \"/cameras/0/orthographic/ymag\"): "
               "key 1 sets the camera ymag to 0 (glTF forbids a view of height 0)");
}

// KHR_animation_pointer's pointers to a light's, a camera's and a material's properties animate
// them (SceneState's lights, cameras and materials; Scene::camera_at takes the camera's yfov);
// a key outside the property's range, or a light, camera or material the file lacks, fails
// naming the channel.
TEST_F(GltfLoaderTest, AnimationPointersToLightsCamerasAndMaterialsAreAnimated) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 1;
  b.doc()["materials"] = json::array(
      {json::object(),
       {{"emissiveFactor", {1, 0.5, 0}},
        {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 2}}}}}}});
  b.doc()["cameras"] = {
      {{"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}}};
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "spot"}, {"intensity", 3}, {"spot", {{"outerConeAngle", 0.5}}}}};
  b.doc()["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  b.doc()["nodes"].push_back({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1, 2};
  const int times = b.add_floats({0, 2}, 1);
  const int scalars = b.add_floats({0.5, 1.5}, 1);
  const int colors = b.add_floats({1, 1, 1, 0, 0, 1}, 3);
  const int factors = b.add_floats({1, 0, 0, 1, 0, 0, 1, 0.5}, 4);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/cameras/0/perspective/yfov"),
         pointer_channel(0, "/extensions/KHR_lights_punctual/lights/0/intensity"),
         pointer_channel(1, "/extensions/KHR_lights_punctual/lights/0/color"),
         pointer_channel(0, "/extensions/KHR_lights_punctual/lights/0/spot/innerConeAngle"),
         pointer_channel(2, "/materials/1/pbrMetallicRoughness/baseColorFactor"),
         pointer_channel(0, "/materials/1/pbrMetallicRoughness/roughnessFactor"),
         pointer_channel(0,
                         "/materials/1/extensions/KHR_materials_emissive_strength/"
                         "emissiveStrength"),
         pointer_channel(0, "/materials/1/alphaCutoff"),
         pointer_channel(0, "/materials/1/normalTexture/scale")}},
       {"samplers",
        {{{"input", times}, {"output", scalars}},
         {{"input", times}, {"output", colors}},
         {{"input", times}, {"output", factors}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_lights_punctual",
                               "KHR_materials_emissive_strength"};
  const fs::path path = dir_ / "properties.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  // Roughness 0.5 to 1.5 goes past 1: clamped, as a roughness factor without an animation is.
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find(
                "animation 0 channel 5 (KHR_animation_pointer "
                "\"/materials/1/pbrMetallicRoughness/roughnessFactor\"): key 1 sets the roughness "
                "factor to 1.5, outside [0, 1]: clamped where it is used"),
            std::string::npos)
      << report.warnings[0];
  ASSERT_EQ(scene.property_channels.size(), 9u);
  EXPECT_EQ(scene.channels.size(), 0u);
  EXPECT_TRUE(scene.is_animated());
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);
  EXPECT_EQ(scene.animated_materials(), std::vector<int>{1});

  const SceneState at1 = scene.evaluate(1.0);  // halfway
  EXPECT_NEAR(scene.camera_at(at1).yfov, 1.0, 1e-6);
  EXPECT_NEAR(scene.camera_at(scene.evaluate(0.0)).yfov, 0.5, 1e-6);
  const Light& light = scene.light_at(at1, 0);
  EXPECT_NEAR(light.intensity, 1.0f, 1e-6f);
  EXPECT_NEAR(light.inner_cone_angle, 1.0f, 1e-6f);
  EXPECT_NEAR(light.outer_cone_angle, 0.5f, 1e-6f);  // not animated
  EXPECT_NEAR(light.color.x, 0.5f, 1e-6f);
  EXPECT_NEAR(light.color.z, 1.0f, 1e-6f);
  const Material& m = scene.material_at(at1, 1);
  EXPECT_NEAR(m.base_color_factor.a, 0.75f, 1e-6f);
  EXPECT_NEAR(m.emissive.x, 1.0f, 1e-6f);  // factor 1 x strength 1
  EXPECT_NEAR(m.emissive.y, 0.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).emissive.x, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.materials[1].emissive.x, 2.0f, 1e-6f);  // the file's, unanimated
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).alpha_cutoff, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).normal_scale, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).roughness, 1.0f, 1e-6f);

  // What is an error without an animation is one with it.
  b.doc()["animations"][0]["channels"].push_back(
      pointer_channel(0, "/materials/0/occlusionTexture/strength"));
  b.write_embedded(path);
  expect_error(path,
               "animation 0 channel 9 (KHR_animation_pointer "
               "\"/materials/0/occlusionTexture/strength\"): key 1 sets the occlusion strength to "
               "1.5, outside [0, 1]");
  b.doc()["animations"][0]["channels"][9] = pointer_channel(0, "/materials/2/emissiveFactor");
  b.write_embedded(path);
  expect_error(path, "targets material 2, but there are 2");
  b.doc()["animations"][0]["channels"][9] =
      pointer_channel(1, "/extensions/KHR_lights_punctual/lights/3/color");
  b.write_embedded(path);
  expect_error(path, "targets light 3, but there are 1");
  b.doc()["animations"][0]["channels"][9] = pointer_channel(0, "/cameras/0/perspective/znear");
  b.doc()["animations"][0]["samplers"][0]["output"] = b.add_floats({0.5, 0}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the camera yfov to 0, outside (0, 3.14159]");
}

// KHR_animation_pointer drives a texture slot's KHR_texture_transform: the slot reads a set of
// its own that holds TEXCOORD_0 untransformed (where the same transform unanimated would share
// the emissive slot's set, transformed at load), and the material's uv_transforms carry the
// file's transform, then the animated one at each time, in a core slot and an extension's.
TEST_F(GltfLoaderTest, AnimationPointersToTextureTransformsAnimateTheirSlotsSets) {
  const DecodedImage gray{1, 1, 3, {128, 128, 128}};
  testing::write_png(gray, dir_ / "gray.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "gray.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  const json turned = {
      {"KHR_texture_transform", {{"offset", {0.5, 0.0}}, {"rotation", 0.5}, {"scale", {2, 3}}}}};
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}, {"extensions", turned}}}}},
        {"emissiveFactor", {1, 1, 1}},
        {"emissiveTexture", {{"index", 0}, {"extensions", turned}}},
        {"extensions",
         {{"KHR_materials_clearcoat",
           {{"clearcoatFactor", 1}, {"clearcoatTexture", {{"index", 0}}}}}}}}});
  const int times = b.add_floats({0, 2}, 1);
  const int offsets = b.add_floats({0, 0, 1, 0.5f}, 2);
  const int angles = b.add_floats({0, 1}, 1);
  const int scales = b.add_floats({1, 1, 3, 5}, 2);
  const std::string base = "/materials/0/pbrMetallicRoughness/baseColorTexture";
  const std::string coat = "/materials/0/extensions/KHR_materials_clearcoat/clearcoatTexture";
  const std::string transform = "/extensions/KHR_texture_transform/";
  b.doc()["animations"] = {{{"channels",
                             {pointer_channel(0, base + transform + "offset"),
                              pointer_channel(1, base + transform + "rotation"),
                              pointer_channel(2, coat + transform + "scale")}},
                            {"samplers",
                             {{{"input", times}, {"output", offsets}},
                              {{"input", times}, {"output", angles}},
                              {{"input", times}, {"output", scales}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_texture_transform",
                               "KHR_materials_clearcoat"};
  const fs::path path = dir_ / "uvs.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.property_channels.size(), 3u);
  EXPECT_EQ(scene.animated_materials(), std::vector<int>{0});
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);

  const Material& m = scene.materials[0];
  EXPECT_EQ(m.uv_set.base_color, 0);  // its own set
  EXPECT_EQ(m.uv_set.emissive, 1);    // the same transform, baked
  EXPECT_EQ(m.uv_set.clearcoat, 2);   // animated: its own, though it reads TEXCOORD_0 as it is
  const Primitive& p = scene.meshes[0].primitives[0];
  const std::vector<glm::vec2> raw = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_EQ(p.uv_set(0), raw);
  EXPECT_EQ(p.uv_set(2), raw);
  // The emissive set: T(0.5, 0) R(0.5) S(2, 3) applied at load; (1, 0) goes to
  // (0.5 + 2 cos 0.5, -2 sin 0.5).
  EXPECT_NEAR(p.uv_set(1)[1].x, 0.5 + 2 * std::cos(0.5), 1e-6);
  EXPECT_NEAR(p.uv_set(1)[1].y, -2 * std::sin(0.5), 1e-6);
  ASSERT_EQ(m.uv_transforms.size(), 3u);
  EXPECT_EQ(m.uv_transforms[0], (Material::UvTransform{{0.5, 0.0}, 0.5, {2.0, 3.0}}));
  EXPECT_EQ(m.uv_transforms[1], Material::UvTransform{});  // baked
  EXPECT_EQ(m.uv_transforms[2], Material::UvTransform{});  // the file has none there
  // The matrix maps (1, 0) where the load maps it.
  const glm::dvec3 moved = m.uv_transforms[0].matrix() * glm::dvec3(1, 0, 1);
  EXPECT_NEAR(moved.x, p.uv_set(1)[1].x, 1e-6);
  EXPECT_NEAR(moved.y, p.uv_set(1)[1].y, 1e-6);

  const SceneState at1 = scene.evaluate(1.0);
  const Material& half = scene.material_at(at1, 0);
  EXPECT_EQ(half.uv_transforms[0].offset, glm::dvec2(0.5, 0.25));
  EXPECT_DOUBLE_EQ(half.uv_transforms[0].rotation, 0.5);
  EXPECT_EQ(half.uv_transforms[0].scale, glm::dvec2(2.0, 3.0));  // not animated: the file's
  EXPECT_EQ(half.uv_transforms[2].scale, glm::dvec2(2.0, 3.0));
  EXPECT_EQ(half.uv_transforms[1], Material::UvTransform{});

  // A pointer to an empty slot is skipped with a warning naming the channel; one to texCoord
  // is a kind afr does not animate; one to a slot afr does not know, likewise.
  b.doc()["animations"][0]["channels"] = {
      pointer_channel(0, "/materials/0/normalTexture/extensions/KHR_texture_transform/offset"),
      pointer_channel(1, base + transform + "texCoord"),
      pointer_channel(0, "/materials/0/nosuchTexture/extensions/KHR_texture_transform/offset")};
  b.write_embedded(path);
  GltfLoadReport skipped;
  const Scene without = load_gltf(path, &skipped);
  EXPECT_TRUE(without.property_channels.empty());
  EXPECT_TRUE(without.materials[0].uv_transforms.empty());
  EXPECT_EQ(without.materials[0].uv_set.base_color, without.materials[0].uv_set.emissive);
  ASSERT_EQ(skipped.warnings.size(), 2u);
  EXPECT_EQ(count_containing(skipped.warnings,
                             "animation 0 channel 0 (KHR_animation_pointer "
                             "\"/materials/0/normalTexture/extensions/KHR_texture_transform/"
                             "offset\") animates the transform of a texture slot without a "
                             "texture (skipped)"),
            1u);
  EXPECT_EQ(count_containing(skipped.warnings, "KHR_texture_transform/texCoord, "), 1u);
  EXPECT_EQ(count_containing(skipped.warnings, "nosuchTexture"), 1u);

  // An offset of the wrong width or not finite, and a material the file lacks, are errors.
  // (json::array: a braced list of one json is that json itself under clang.)
  b.doc()["animations"][0]["channels"] =
      json::array({pointer_channel(1, base + transform + "offset")});
  b.write_embedded(path);
  expect_error(path, "animation 0 channel 0");
  b.doc()["animations"][0]["channels"] = json::array(
      {pointer_channel(0, "/materials/4/emissiveTexture/extensions/KHR_texture_transform/offset")});
  b.write_embedded(path);
  expect_error(path, "targets material 4, but there are 1");
}

// KHR_animation_pointer drives a node's KHR_node_visibility: the node keeps its mesh though the
// file hides it at rest (Node::visible false), its visibility and its child's vary, and each key
// holds until the next (a visibility does not blend, whatever the interpolation). A node hidden
// with no animation still loses its mesh.
TEST_F(GltfLoaderTest, AnimationPointersToANodesVisibilityShowAndHideItAndItsChildren) {
  GltfBuilder b;
  add_quad(&b);
  const json hidden = {{"KHR_node_visibility", {{"visible", false}}}};
  b.doc()["nodes"][0]["extensions"] = hidden;
  b.doc()["nodes"][0]["children"] = {1};
  b.doc()["nodes"].push_back({{"mesh", 0}, {"translation", {0, 2, 0}}});  // node 1: its child
  b.doc()["nodes"].push_back({{"mesh", 0}, {"extensions", hidden}});      // node 2: for good
  b.doc()["scenes"][0]["nodes"] = {0, 2};
  const int times = b.add_floats({0, 1, 2}, 1);
  const int keys = b.add_floats({0, 1, 0}, 1);
  b.doc()["animations"] = {
      {{"channels",
        json::array({pointer_channel(0, "/nodes/0/extensions/KHR_node_visibility/visible")})},
       {"samplers", {{{"input", times}, {"output", keys}}}}}};  // LINEAR, the default
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_node_visibility"};
  const fs::path path = dir_ / "blink.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.property_channels.size(), 1u);
  EXPECT_TRUE(scene.animated_materials().empty());
  EXPECT_EQ(scene.nodes[0].mesh, 0);
  EXPECT_FALSE(scene.nodes[0].visible);
  EXPECT_TRUE(scene.nodes[1].visible);
  EXPECT_EQ(scene.nodes[2].mesh, -1);  // hidden for good: dropped
  EXPECT_TRUE(scene.node_visibility_varies(0));
  EXPECT_TRUE(scene.node_visibility_varies(1));
  EXPECT_FALSE(scene.node_visibility_varies(2));
  for (const auto& [t, shown] : std::vector<std::pair<double, bool>>{
           {0.0, false}, {0.9, false}, {1.0, true}, {1.5, true}, {2.0, false}, {5.0, false}}) {
    const SceneState state = scene.evaluate(t);
    EXPECT_EQ(scene.node_hidden(state, 0), !shown) << "t = " << t;
    EXPECT_EQ(scene.node_hidden(state, 1), !shown) << "t = " << t;  // with its parent
  }

  // A pointer to a node the file lacks is an error naming it; a negative key, one naming it.
  b.doc()["animations"][0]["channels"][0] =
      pointer_channel(0, "/nodes/7/extensions/KHR_node_visibility/visible");
  b.write_embedded(path);
  expect_error(path, "targets node 7, but there are 3");
  b.doc()["animations"][0]["channels"][0] =
      pointer_channel(0, "/nodes/1/extensions/KHR_node_visibility/visible");
  b.doc()["animations"][0]["samplers"][0]["output"] = b.add_floats({1, -1, 1}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the node visibility to -1");
}

// The material extensions' factors are animated within the ranges the loader reads them in:
// a color's three components and a factor's one reach the material, a key outside the range is
// an error naming the channel and the key.
TEST_F(GltfLoaderTest, AnimationPointersToMaterialExtensionFactorsKeepTheirRanges) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_sheen", {{"sheenColorFactor", {0, 0, 0}}}},
                      {"KHR_materials_iridescence", {{"iridescenceFactor", 1}}}}}}});
  const int times = b.add_floats({0, 2}, 1);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/materials/0/extensions/KHR_materials_sheen/sheenColorFactor"),
         pointer_channel(1, "/materials/0/extensions/KHR_materials_iridescence/iridescenceIor")}},
       {"samplers",
        {{{"input", times}, {"output", b.add_floats({0, 0, 0, 1, 0.5f, 0.25f}, 3)}},
         {{"input", times}, {"output", b.add_floats({1.2f, 2.0f}, 1)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_materials_sheen",
                               "KHR_materials_iridescence"};
  const fs::path path = dir_ / "factors.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  const SceneState at1 = scene.evaluate(1.0);
  const Material& m = scene.material_at(at1, 0);
  EXPECT_NEAR(m.sheen_color.x, 0.5f, 1e-6f);
  EXPECT_NEAR(m.sheen_color.y, 0.25f, 1e-6f);
  EXPECT_NEAR(m.sheen_color.z, 0.125f, 1e-6f);
  EXPECT_NEAR(m.iridescence_ior, 1.6f, 1e-6f);

  b.doc()["animations"][0]["samplers"][1]["output"] = b.add_floats({1.2f, 0.9f}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the iridescence ior to 0.9");
  b.doc()["animations"][0]["channels"][1] =
      pointer_channel(1, "/materials/0/extensions/KHR_materials_clearcoat/clearcoatFactor");
  b.doc()["animations"][0]["samplers"][1]["output"] = b.add_floats({0.5f, 1.5f}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the clearcoat factor to 1.5, outside [0, 1]");
}

// Transmission, ior, volume, dispersion and diffuse transmission animate too (the tracer gives a
// material whose transmission is animated the glass filter whatever it is at the start), each
// within its range: an animated ior stays at or above 1 (KHR_materials_ior's 0 would pass through
// (0, 1) between keys) and an attenuation distance above 0.
TEST_F(GltfLoaderTest, AnimationPointersToTransmissionAndVolumeKeepTheirRanges) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] = json::array({json::object()});
  const int times = b.add_floats({0, 2}, 1);
  const std::string m = "/materials/0/extensions/";
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, m + "KHR_materials_transmission/transmissionFactor"),
         pointer_channel(1, m + "KHR_materials_ior/ior"),
         pointer_channel(2, m + "KHR_materials_volume/thicknessFactor"),
         pointer_channel(3, m + "KHR_materials_volume/attenuationDistance"),
         pointer_channel(4, m + "KHR_materials_volume/attenuationColor"),
         pointer_channel(5, m + "KHR_materials_dispersion/dispersion"),
         pointer_channel(6, m + "KHR_materials_diffuse_transmission/diffuseTransmissionFactor"),
         pointer_channel(7,
                         m + "KHR_materials_diffuse_transmission/diffuseTransmissionColorFactor")}},
       {"samplers",
        {{{"input", times}, {"output", b.add_floats({0, 1}, 1)}},
         {{"input", times}, {"output", b.add_floats({1.5f, 1.1f}, 1)}},
         {{"input", times}, {"output", b.add_floats({0, 2}, 1)}},
         {{"input", times}, {"output", b.add_floats({4, 2}, 1)}},
         {{"input", times}, {"output", b.add_floats({1, 1, 1, 0.5f, 0.25f, 0}, 3)}},
         {{"input", times}, {"output", b.add_floats({0, 3}, 1)}},
         {{"input", times}, {"output", b.add_floats({0, 0.5f}, 1)}},
         {{"input", times}, {"output", b.add_floats({1, 1, 1, 0, 0.5f, 1}, 3)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "volume.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_EQ(scene.materials[0].transmission, 0.0f);  // the file's, where the animation starts
  const SceneState state = scene.evaluate(1.0);
  const Material& at1 = scene.material_at(state, 0);
  EXPECT_NEAR(at1.transmission, 0.5f, 1e-6f);
  EXPECT_NEAR(at1.ior, 1.3f, 1e-6f);
  EXPECT_NEAR(at1.thickness, 1.0f, 1e-6f);
  EXPECT_NEAR(at1.attenuation_distance, 3.0f, 1e-6f);
  EXPECT_NEAR(at1.attenuation_color.y, 0.625f, 1e-6f);
  EXPECT_NEAR(at1.dispersion, 1.5f, 1e-6f);
  EXPECT_NEAR(at1.diffuse_transmission, 0.25f, 1e-6f);
  EXPECT_NEAR(at1.diffuse_transmission_color.x, 0.5f, 1e-6f);
  EXPECT_NEAR(at1.diffuse_transmission_color.y, 0.75f, 1e-6f);

  const auto refused = [&](int sampler, const std::vector<float>& keys, int width,
                           const std::string& problem) {
    json doc = b.doc();
    b.doc()["animations"][0]["samplers"][sampler]["output"] = b.add_floats(keys, width);
    b.write_embedded(path);
    expect_error(path, problem);
    b.doc() = doc;
  };
  refused(0, {0, 1.2f}, 1, "key 1 sets the transmission factor to 1.2, outside [0, 1]");
  refused(1, {1.5f, 0}, 1, "key 1 sets the ior to 0, outside [1, inf]");
  refused(2, {-1, 0}, 1, "key 0 sets the thickness factor to -1, outside [0, inf]");
  refused(3, {4, 0}, 1, "key 1 sets the attenuation distance to 0, outside (0, inf]");
  refused(4, {1, 1, 1, 0.5f, 1.5f, 0}, 3,
          "key 1 sets the attenuation color to 1.5, outside [0, 1]");
  refused(5, {0, -2}, 1, "key 1 sets the dispersion to -2, outside [0, inf]");
  refused(6, {0, 2}, 1, "key 1 sets the diffuse transmission factor to 2, outside [0, 1]");
  refused(7, {1, 1, 1, 0, -1, 0}, 3,
          "key 1 sets the diffuse transmission color to -1, outside [0, 1]");
}

// glTF requires strictly increasing keyframe times, but exporters write repeated and unordered
// ones: the channel is repaired with a warning naming it, not the whole scene refused.
TEST_F(GltfLoaderTest, KeyframeTimesOutOfOrderAreSortedWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  const int times = b.add_floats({0, 2, 1, 1}, 1);
  const int values = b.add_floats({0, 0, 0, 2, 0, 0, 5, 0, 0, 1, 0, 0}, 3);
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}},
        {"samplers", {{{"input", times}, {"output", values}}}}}});
  const fs::path path = dir_ / "unordered.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("animation 0 channel 0"), std::string::npos)
      << report.warnings[0];
  EXPECT_NE(report.warnings[0].find("1 of 4 dropped"), std::string::npos) << report.warnings[0];
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].times, (std::vector<double>{0.0, 1.0, 2.0}));
  EXPECT_DOUBLE_EQ(scene.channels[0].evaluate(1.5).x, 1.5);  // keys (1, 1) and (2, 2)
}

}  // namespace
}  // namespace afr
