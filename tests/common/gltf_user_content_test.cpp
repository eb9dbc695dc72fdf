// Tests of what the loader does for glTF content made elsewhere (issue 18): the default
// lighting of a scene without lights and its one log line, the default camera that frames a
// whole animation, unknown required and used extensions, KHR_materials_emissive_strength,
// KHR_materials_transmission, KHR_materials_ior and KHR_texture_transform. References are written
// out by hand from the glTF texts.
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>

#include "support/png.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "support/gltf_content.h"
#include "support/log_capture.h"

namespace afr {
namespace {

using json = nlohmann::json;
using testing::GltfContent;
using testing::LogCapture;
using testing::TempFolder;

// Where a light on the camera shines, in the camera's frame: (right, up, forward) components.
glm::dvec3 direction_in_camera(const Light& light) {
  const glm::dvec3 d = light.camera_rotation * glm::dvec3(0.0, 0.0, -1.0);  // its -Z
  return {d.x, d.y, -d.z};
}

// A box with a plain material and nothing else: no lights, no camera (like BoxAnimated).
GltfContent unlit_box() {
  GltfContent g;
  g.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness",
                     {{"baseColorFactor", {0.8, 0.4, 0.8, 1.0}}, {"metallicFactor", 0.0}}}}});
  const int box = g.add_box(0.5f, 0);
  g.set_roots({g.add_node({{"mesh", box}})});
  return g;
}

// ---- Default lighting ----

TEST(GltfUserContentTest, SceneWithoutLightsGetsAHeadlightAndSkyAndSaysSoOnce) {
  TempFolder dir;
  unlit_box().write(dir / "box.gltf");
  LogCapture log;
  GltfLoadReport report;
  const Scene scene = load_gltf(dir / "box.gltf", &report);

  // One info line, naming the file and what was added; nothing else logged.
  const std::vector<std::string> lines = log.lines_with("default lighting");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("info ", 0), 0u) << lines[0];
  EXPECT_NE(lines[0].find("box.gltf"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find("no lights"), std::string::npos) << lines[0];
  EXPECT_EQ(log.count_level("info"), 1u);
  EXPECT_TRUE(report.warnings.empty());

  // A directional light in the displayed scene, and a grey sky as the ambient term.
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_EQ(scene.lights[0].type, Light::Type::kDirectional);
  EXPECT_GT(scene.lights[0].intensity, 0.0f);
  EXPECT_GT(scene.ambient.g, 0.0f);
  EXPECT_EQ(scene.ambient.r, scene.ambient.g);
  EXPECT_EQ(scene.ambient.b, scene.ambient.g);
  // The sky is the background too (what mirrors reflect and glass shows), as the line says.
  EXPECT_EQ(scene.background, scene.ambient);
  EXPECT_NE(lines[0].find("a sky of 0.2 (the ambient light and the background)"), std::string::npos)
      << lines[0];

  // A headlight: on the camera, no node of its own, shining roughly where the camera looks
  // and from above the view, in the camera's frame whichever camera that is.
  EXPECT_TRUE(scene.lights[0].on_camera);
  for (const Node& n : scene.nodes) EXPECT_EQ(n.light, -1);
  const glm::dvec3 d = direction_in_camera(scene.lights[0]);
  EXPECT_NEAR(glm::length(d), 1.0, 1e-12);
  EXPECT_GT(d.z, std::cos(40.0 * std::numbers::pi / 180.0));
  EXPECT_LT(d.y, 0.0);  // shines downward: comes from above
}

TEST(GltfUserContentTest, AFileCameraKeepsTheHeadlightOnIt) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["cameras"] =
      json::array({{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.1}}}}});
  const int camera = g.add_node({{"camera", 0}, {"translation", {0, 0, 4}}});
  g.set_roots({0, camera});
  g.write(dir / "camera.gltf");
  LogCapture log;
  const Scene scene = load_gltf(dir / "camera.gltf");
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_TRUE(scene.lights[0].on_camera);
  EXPECT_EQ(scene.nodes.size(), 2u);  // the file's nodes, no more
  const std::vector<std::string> lines = log.lines_with("default lighting");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("camera node 1"), std::string::npos) << lines[0];
}

TEST(GltfUserContentTest, ScenesThatBringLightOrAmbientGetNoDefaultAndABackgroundStays) {
  TempFolder dir;
  GltfContent lit = unlit_box();
  lit.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
  lit.doc()["extensions"]["KHR_lights_punctual"]["lights"] =
      json::array({{{"type", "point"}, {"intensity", 10.0}}});
  const int lamp = lit.add_node({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  lit.set_roots({0, lamp});
  lit.write(dir / "lit.gltf");

  GltfContent ambient = unlit_box();
  ambient.doc()["scenes"][0]["extras"]["afr_ambient"] = {0.1, 0.1, 0.1};
  ambient.write(dir / "ambient.gltf");

  GltfContent backdrop = unlit_box();
  backdrop.doc()["scenes"][0]["extras"]["afr_background"] = {0.0, 0.0, 0.5};
  backdrop.write(dir / "backdrop.gltf");

  {
    // A file's background stays: the default lighting then adds only the headlight and the
    // ambient sky.
    LogCapture log;
    const Scene with_backdrop = load_gltf(dir / "backdrop.gltf");
    EXPECT_EQ(with_backdrop.background, glm::vec3(0.0f, 0.0f, 0.5f));
    EXPECT_EQ(with_backdrop.ambient, glm::vec3(0.2f));
    const std::vector<std::string> lines = log.lines_with("default lighting");
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_NE(lines[0].find("a sky of 0.2 (the ambient light)"), std::string::npos) << lines[0];
  }

  LogCapture log;
  const Scene with_lamp = load_gltf(dir / "lit.gltf");
  EXPECT_EQ(with_lamp.lights.size(), 1u);
  EXPECT_EQ(with_lamp.nodes.size(), 2u);
  EXPECT_EQ(with_lamp.ambient, glm::vec3(0.0f));
  const Scene with_ambient = load_gltf(dir / "ambient.gltf");
  EXPECT_TRUE(with_ambient.lights.empty());
  EXPECT_EQ(with_ambient.ambient, glm::vec3(0.1f));
  EXPECT_TRUE(log.lines_with("default lighting").empty());
}

// ---- Default camera ----

// A scene flat in y (a ground lying in xz, as Khronos's TwoSidedPlane) is seen edge on from
// +Z: the default camera looks down on it from 45 degrees instead, and sees it whole.
TEST(GltfUserContentTest, DefaultCameraLooksDownOnAFlatScene) {
  TempFolder dir;
  GltfContent g;
  g.add_mesh({-2, 0, -1, 2, 0, -1, 2, 0, 1, -2, 0, 1}, {0, 2, 1, 0, 3, 2});
  g.doc()["nodes"] = json::array({{{"mesh", 0}}});
  g.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  g.write(dir / "ground.gltf");
  const Scene scene = load_gltf(dir / "ground.gltf");
  const Camera camera = scene.camera_at(scene.evaluate(0.0));
  EXPECT_NEAR(camera.forward.y, -std::sqrt(0.5), 1e-9);  // 45 degrees down
  EXPECT_NEAR(camera.forward.x, 0.0, 1e-9);
  const int kSize = 100;
  double top = kSize, bottom = 0.0;
  for (const glm::dvec3 corner :
       {glm::dvec3(-2, 0, -1), glm::dvec3(2, 0, -1), glm::dvec3(2, 0, 1), glm::dvec3(-2, 0, 1)}) {
    glm::dvec2 xy;
    ASSERT_TRUE(camera.project(corner, kSize, kSize, &xy, nullptr));
    EXPECT_GE(xy.x, 0.0);
    EXPECT_LE(xy.x, kSize);
    top = std::min(top, xy.y);
    bottom = std::max(bottom, xy.y);
  }
  EXPECT_GE(top, 0.0);
  EXPECT_LE(bottom, kSize);
  EXPECT_GT(bottom - top, 0.2 * kSize);  // seen as an area, not a line
}

TEST(GltfUserContentTest, DefaultCameraFramesTheWholeAnimationOnce) {
  // A box sliding 6 units along +X and back up over 3 s, keyed late (from 0.5 s) as exported
  // content often is; no camera in the file.
  TempFolder dir;
  GltfContent g = unlit_box();
  g.animate_translation(0, {0.5f, 2.0f, 3.0f}, {-3, 0, 0, 3, 0, 0, 3, 1, 0});
  g.write(dir / "sliding.gltf");
  const Scene scene = load_gltf(dir / "sliding.gltf");
  ASSERT_EQ(scene.camera_node(), -1);

  const int kSize = 200;
  const Camera first = scene.camera_at(scene.evaluate(0.0));
  auto image_center = [&](double t) {
    const SceneState state = scene.evaluate(t);
    const Camera camera = scene.camera_at(state);
    // One camera for the whole animation.
    EXPECT_EQ(camera.eye, first.eye) << "t = " << t;
    EXPECT_EQ(camera.forward, first.forward) << "t = " << t;
    EXPECT_EQ(camera.yfov, first.yfov) << "t = " << t;
    // Every corner of the box is inside the image at every time, keys and between.
    for (int corner = 0; corner < 8; ++corner) {
      const glm::dvec3 local((corner & 1) ? 0.5 : -0.5, (corner & 2) ? 0.5 : -0.5,
                             (corner & 4) ? 0.5 : -0.5);
      glm::dvec2 xy;
      EXPECT_TRUE(camera.project(glm::dvec3(state.world[0] * glm::dvec4(local, 1.0)), kSize, kSize,
                                 &xy, nullptr));
      EXPECT_GE(xy.x, 0.0) << "t = " << t;
      EXPECT_LE(xy.x, kSize) << "t = " << t;
      EXPECT_GE(xy.y, 0.0) << "t = " << t;
      EXPECT_LE(xy.y, kSize) << "t = " << t;
    }
    glm::dvec2 center;
    EXPECT_TRUE(camera.project(glm::dvec3(state.world[0][3]), kSize, kSize, &center, nullptr));
    return center;
  };
  for (double t = 0.0; t <= 3.0; t += 0.125) image_center(t);
  // The box crosses the image from left to right, and rises at the end.
  const glm::dvec2 start = image_center(0.0);
  const glm::dvec2 middle = image_center(2.0);
  const glm::dvec2 end = image_center(3.0);
  EXPECT_LT(start.x, 0.35 * kSize);
  EXPECT_GT(middle.x, 0.65 * kSize);
  EXPECT_NEAR(start.y, middle.y, 1e-6);
  EXPECT_LT(end.y, middle.y - 0.05 * kSize);  // image y points down
}

TEST(GltfUserContentTest, AnOrthographicCameraViewsTheSceneAlongItsAxis) {
  TempFolder dir;
  GltfContent g = unlit_box();
  // xmag is not used: the width follows from the image, as a perspective camera's does. A near
  // plane at 0 is allowed for an orthographic camera.
  g.doc()["cameras"] =
      json::array({{{"type", "orthographic"},
                    {"name", "plan view"},
                    {"orthographic", {{"xmag", 3}, {"ymag", 2}, {"znear", 0}, {"zfar", 10}}}}});
  g.set_roots({0, g.add_node({{"camera", 0}, {"translation", {0, 0, 3}}})});
  g.write(dir / "ortho.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir / "ortho.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings[0];
  ASSERT_NE(scene.camera_node(), -1);
  const Camera camera = scene.camera_at(scene.evaluate(0.0));
  ASSERT_TRUE(camera.orthographic());
  EXPECT_EQ(camera.ymag, 2.0);
  EXPECT_GT(camera.znear, 0.0);
  EXPECT_LT(camera.znear, 1e-6);
  // The box's front and back corners land on the same pixel, a quarter of the half height
  // (0.5 of 2) right of and above the center of a 200 x 200 image.
  for (double z : {0.5, -0.5}) {
    glm::dvec2 xy;
    ASSERT_TRUE(camera.project(glm::dvec3(0.5, 0.5, z), 200, 200, &xy, nullptr));
    EXPECT_NEAR(xy.x, 125.0, 1e-9);
    EXPECT_NEAR(xy.y, 75.0, 1e-9);
  }
  // Every ray runs along the view; the corner pixel's starts 2 x 2 units from the axis.
  const Ray corner = camera.ray(0.0, 0.0, 200, 200);
  EXPECT_NEAR(corner.direction.z, -1.0f, 1e-7f);
  EXPECT_NEAR(corner.origin.x, -2.0f, 1e-6f);
  EXPECT_NEAR(corner.origin.y, 2.0f, 1e-6f);

  // glTF asks writers not to give a negative ymag: its magnitude is used, with a warning.
  g.doc()["cameras"][0]["orthographic"]["ymag"] = -2;
  g.write(dir / "negative.gltf");
  GltfLoadReport negative;
  EXPECT_EQ(load_gltf(dir / "negative.gltf", &negative).cameras.at(0).ymag, 2.0);
  ASSERT_EQ(negative.warnings.size(), 1u);
  EXPECT_NE(negative.warnings[0].find("camera 0 ('plan view') has a negative ymag (-2)"),
            std::string::npos)
      << negative.warnings[0];
  // A ymag of 0 is no view at all.
  g.doc()["cameras"][0]["orthographic"]["ymag"] = 0;
  g.write(dir / "flat.gltf");
  try {
    load_gltf(dir / "flat.gltf");
    ADD_FAILURE() << "a ymag of 0 loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("camera 0 ('plan view') is orthographic with a ymag of "
                                         "0: glTF requires a finite ymag other than 0"),
              std::string::npos)
        << e.what();
  }
  // Each field out of its range is named, in either kind of camera.
  const auto error_of = [&](const json& camera) -> std::string {
    g.doc()["cameras"][0] = camera;
    g.write(dir / "bad.gltf");
    try {
      load_gltf(dir / "bad.gltf");
    } catch (const Error& e) {
      return e.what();
    }
    return "loaded";
  };
  EXPECT_NE(error_of({{"type", "orthographic"},
                      {"orthographic", {{"xmag", 1}, {"ymag", 1}, {"znear", -1}, {"zfar", 9}}}})
                .find("camera 0 is orthographic with a znear of -1: glTF requires a finite znear "
                      ">= 0"),
            std::string::npos);
  EXPECT_NE(error_of({{"type", "perspective"}, {"perspective", {{"yfov", 4}, {"znear", 1}}}})
                .find("camera 0 has a yfov of 4 radians, outside (0, pi)"),
            std::string::npos);
  EXPECT_NE(error_of({{"type", "perspective"}, {"perspective", {{"yfov", 1}, {"znear", 0}}}})
                .find("camera 0 has a znear of 0: a perspective camera's is finite and > 0"),
            std::string::npos);
}

// ---- Extensions ----

TEST(GltfUserContentTest, AnUnsupportedRequiredExtensionIsAnErrorNamingIt) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["extensionsUsed"] = {"KHR_texture_basisu", "KHR_texture_transform"};
  g.doc()["extensionsRequired"] = {"KHR_texture_basisu", "KHR_texture_transform"};
  g.write(dir / "basisu.gltf");
  try {
    load_gltf(dir / "basisu.gltf");
    ADD_FAILURE() << "a file requiring KHR_texture_basisu loaded";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("basisu.gltf"), std::string::npos) << what;
    EXPECT_NE(what.find("requires"), std::string::npos) << what;
    EXPECT_NE(what.find("KHR_texture_basisu"), std::string::npos) << what;
    // A required extension afr reads is not the problem.
    EXPECT_EQ(what.find("KHR_texture_transform"), std::string::npos) << what;
  }
}

TEST(GltfUserContentTest, AnUnsupportedUsedExtensionIsOneWarningNamingIt) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["extensionsUsed"] = {"ADOBE_materials_thin_transparency",
                               "KHR_materials_emissive_strength"};
  g.doc()["extensionsRequired"] = {"KHR_materials_emissive_strength"};
  g.doc()["materials"][0]["extensions"] = {
      {"ADOBE_materials_thin_transparency", {{"transmissionFactor", 0.5}}},
      {"KHR_materials_emissive_strength", {{"emissiveStrength", 2.0}}}};
  g.write(dir / "thin_transparency.gltf");
  LogCapture log;
  GltfLoadReport report;
  load_gltf(dir / "thin_transparency.gltf", &report);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("ADOBE_materials_thin_transparency"), std::string::npos);
  EXPECT_EQ(log.lines_with("ADOBE_materials_thin_transparency").size(), 1u);
  EXPECT_EQ(log.count_level("warning"), 1u);
}

TEST(GltfUserContentTest, EmissiveStrengthScalesTheEmissiveFactor) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  g.doc()["materials"][0]["emissiveFactor"] = {1.0, 0.5, 0.25};
  g.doc()["materials"][0]["extensions"] = {
      {"KHR_materials_emissive_strength", {{"emissiveStrength", 6.0}}}};
  g.doc()["materials"].push_back({{"emissiveFactor", {0.5, 0.5, 0.5}}});  // no strength: 1
  g.write(dir / "bright.gltf");
  const Scene scene = load_gltf(dir / "bright.gltf");
  EXPECT_EQ(scene.materials[0].emissive, glm::vec3(6.0f, 3.0f, 1.5f));
  EXPECT_EQ(scene.materials[1].emissive, glm::vec3(0.5f));

  g.doc()["materials"][0]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] =
      -1.0;
  g.write(dir / "negative.gltf");
  EXPECT_THROW(load_gltf(dir / "negative.gltf"), Error);
}

TEST(GltfUserContentTest, TransmissionAndIorAreReadWithTheirDefaults) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["extensionsUsed"] = {"KHR_materials_transmission", "KHR_materials_ior"};
  g.doc()["extensionsRequired"] = {"KHR_materials_transmission"};
  g.doc()["materials"][0]["extensions"] = {
      {"KHR_materials_transmission", {{"transmissionFactor", 0.85}}},
      {"KHR_materials_ior", {{"ior", 1.33}}}};
  // Both extensions present but empty: transmission 0, ior 1.5.
  g.doc()["materials"].push_back(
      {{"extensions",
        {{"KHR_materials_transmission", json::object()}, {"KHR_materials_ior", json::object()}}}});
  g.doc()["materials"].push_back(json::object());  // neither extension
  // ior 0 is allowed by KHR_materials_ior (a Fresnel term of 1).
  g.doc()["materials"].push_back({{"extensions", {{"KHR_materials_ior", {{"ior", 0.0}}}}}});
  g.write(dir / "glass.gltf");
  LogCapture log;
  GltfLoadReport report;
  const Scene scene = load_gltf(dir / "glass.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 4u);
  EXPECT_FLOAT_EQ(scene.materials[0].transmission, 0.85f);
  EXPECT_FLOAT_EQ(scene.materials[0].ior, 1.33f);
  EXPECT_EQ(scene.materials[1].transmission, 0.0f);
  EXPECT_EQ(scene.materials[1].ior, 1.5f);
  EXPECT_EQ(scene.materials[2].transmission, 0.0f);
  EXPECT_EQ(scene.materials[2].ior, 1.5f);
  EXPECT_EQ(scene.materials[3].ior, 0.0f);
  EXPECT_TRUE(report.warnings.empty());  // both are read, neither is "ignored"
}

// A transmissionTexture is read (GltfLoaderTest.MaterialExtensionTexturesAreRead); one naming a
// texture the file does not have fails naming the material, the slot and the file.
TEST(GltfUserContentTest, ATransmissionTextureNamingNoTextureFailsNamingIt) {
  TempFolder dir;
  GltfContent g = unlit_box();
  g.doc()["extensionsUsed"] = {"KHR_materials_transmission"};
  g.doc()["materials"][0]["extensions"] = {
      {"KHR_materials_transmission",
       {{"transmissionFactor", 0.5}, {"transmissionTexture", {{"index", 0}}}}}};
  g.write(dir / "textured_glass.gltf");
  try {
    load_gltf(dir / "textured_glass.gltf");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("material 0 transmissionTexture refers to texture 0, but there are 0"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("textured_glass.gltf"), std::string::npos) << what;
  }
}

TEST(GltfUserContentTest, BadTransmissionOrIorFailsNamingTheMaterialAndValue) {
  TempFolder dir;
  const auto expect_failure = [&](const json& extensions, const std::string& part) {
    GltfContent g = unlit_box();
    g.doc()["extensionsUsed"] = {"KHR_materials_transmission", "KHR_materials_ior"};
    g.doc()["materials"][0]["extensions"] = extensions;
    g.write(dir / "bad.gltf");
    try {
      load_gltf(dir / "bad.gltf");
      ADD_FAILURE() << "no error for " << extensions.dump();
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("material 0"), std::string::npos) << what;
      EXPECT_NE(what.find(part), std::string::npos) << what;
      EXPECT_NE(what.find("bad.gltf"), std::string::npos) << what;
    }
  };
  expect_failure({{"KHR_materials_transmission", {{"transmissionFactor", 1.5}}}},
                 "transmissionFactor");
  expect_failure({{"KHR_materials_transmission", {{"transmissionFactor", -0.1}}}},
                 "transmissionFactor");
  expect_failure({{"KHR_materials_transmission", {{"transmissionFactor", "glass"}}}},
                 "transmissionFactor");
  expect_failure({{"KHR_materials_ior", {{"ior", 0.5}}}}, "ior");
  expect_failure({{"KHR_materials_ior", {{"ior", -1.5}}}}, "ior");
  expect_failure({{"KHR_materials_ior", {{"ior", "water"}}}}, "ior");
}

// The bytes of a 1x1 PNG.
std::vector<uint8_t> tiny_png(const TempFolder& dir) {
  const std::filesystem::path path = dir / "tiny.png";
  testing::write_png(DecodedImage{1, 1, 3, {200, 100, 50}}, path);
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A quad with uvs (0,0)..(1,1) and a PNG texture on material 0 carrying `transform`.
GltfContent textured_quad(const json& transform, const std::vector<uint8_t>& png) {
  GltfContent g;
  g.doc()["images"] = json::array({{{"uri", "data:image/png;base64," + testing::base64(png)}}});
  g.doc()["textures"] = json::array({{{"source", 0}}});
  json info = {{"index", 0}};
  if (!transform.is_null()) info["extensions"]["KHR_texture_transform"] = transform;
  g.doc()["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", info}}}}});
  g.doc()["extensionsUsed"] = {"KHR_texture_transform"};
  const int mesh = g.add_mesh({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}, 0,
                              {0, 0, 1, 0, 1, 1, 0, 1});
  g.set_roots({g.add_node({{"mesh", mesh}})});
  return g;
}

TEST(GltfUserContentTest, TextureTransformMovesTheTextureCoordinates) {
  // KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv, where R turns the u axis
  // toward -v (the sample viewer's convention, checked by TextureTransformTest's markers).
  struct Case {
    json transform;
    glm::dvec2 (*expected)(glm::dvec2);
  };
  const std::vector<Case> cases = {
      {json(nullptr), [](glm::dvec2 uv) { return uv; }},
      {{{"offset", {0.5, -0.25}}}, [](glm::dvec2 uv) { return uv + glm::dvec2(0.5, -0.25); }},
      {{{"scale", {2.0, 3.0}}}, [](glm::dvec2 uv) { return glm::dvec2(2 * uv.x, 3 * uv.y); }},
      // A quarter turn: u' = v, v' = -u.
      {{{"rotation", std::numbers::pi / 2}}, [](glm::dvec2 uv) { return glm::dvec2(uv.y, -uv.x); }},
      // All three: scale first, then turn, then move.
      {{{"offset", {1.0, 2.0}}, {"rotation", std::numbers::pi / 2}, {"scale", {2.0, 3.0}}},
       [](glm::dvec2 uv) { return glm::dvec2(3 * uv.y + 1.0, -2 * uv.x + 2.0); }},
  };
  TempFolder dir;
  const std::vector<uint8_t> png = tiny_png(dir);
  for (size_t c = 0; c < cases.size(); ++c) {
    SCOPED_TRACE(cases[c].transform.dump());
    textured_quad(cases[c].transform, png).write(dir / "quad.gltf");
    GltfLoadReport report;
    const Scene scene = load_gltf(dir / "quad.gltf", &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    const std::vector<glm::vec2>& uvs = scene.meshes.at(0).primitives.at(0).uvs;
    const std::vector<glm::dvec2> source = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    ASSERT_EQ(uvs.size(), source.size());
    for (size_t i = 0; i < source.size(); ++i) {
      const glm::dvec2 want = cases[c].expected(source[i]);
      EXPECT_NEAR(uvs[i].x, want.x, 1e-6) << "vertex " << i;
      EXPECT_NEAR(uvs[i].y, want.y, 1e-6) << "vertex " << i;
    }
  }
}

TEST(GltfUserContentTest, TextureTransformTexCoordAndBadValuesAreReported) {
  TempFolder dir;
  const std::vector<uint8_t> png = tiny_png(dir);
  // texCoord in the transform replaces the reference's: TEXCOORD_1 is not read (a warning).
  textured_quad({{"texCoord", 1}}, png).write(dir / "uv1.gltf");
  GltfLoadReport report;
  load_gltf(dir / "uv1.gltf", &report);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("TEXCOORD_1"), std::string::npos) << report.warnings[0];

  textured_quad({{"scale", {1.0}}}, png).write(dir / "bad.gltf");
  try {
    load_gltf(dir / "bad.gltf");
    ADD_FAILURE() << "a scale of one number loaded";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("KHR_texture_transform"), std::string::npos) << what;
    EXPECT_NE(what.find("scale"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace afr
