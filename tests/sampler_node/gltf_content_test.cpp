// The tracer on glTF content made elsewhere (issue 18), loaded through the loader as the
// sampler loads it: a scene without lights renders non-black under the default lighting (the
// Lambert law written out by hand for the headlight and sky), the headlight follows an
// animated camera, emission scaled by KHR_materials_emissive_strength, the default camera
// shows a moving object moving across the image, an animated KHR_texture_transform moves a
// texture over its surface, and an animated KHR_node_visibility shows and hides nodes.
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>

#include <afr/sampler/tracer.h>
#include "support/png.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "support/deforming_content.h"
#include "support/gltf_content.h"

namespace afr {
namespace {

using json = nlohmann::json;
using testing::GltfContent;
using testing::TempFolder;

// The default lighting as docs/scene-model.md states it: a directional headlight of intensity
// 2.5 from (0.35, 0.5, 1) in the camera's frame and a sky of 0.2.
constexpr double kHeadlightIntensity = 2.5;
constexpr double kSky = 0.2;
const glm::dvec3 kFromInCamera = glm::normalize(glm::dvec3(0.35, 0.5, 1.0));

// A Lambertian face (metallic 0, roughness 1: no specular lobe) of base color `base` whose
// normal, in the camera's frame, is `n`: sky plus headlight, by hand.
glm::dvec3 lambert_under_default_light(const glm::dvec3& base, const glm::dvec3& n) {
  const double cos_l = std::max(glm::dot(n, kFromInCamera), 0.0);
  return base * (kSky + kHeadlightIntensity / std::numbers::pi * cos_l);
}

// A box of half size 0.5 at the origin with one plain Lambertian material, as mesh 0 on node 0.
GltfContent box(const json& material) {
  GltfContent g;
  g.doc()["materials"] = json::array({material});
  g.set_roots({g.add_node({{"mesh", g.add_box(0.5f, 0)}})});
  return g;
}

const json kPurple = {{"pbrMetallicRoughness",
                       {{"baseColorFactor", {0.8, 0.4, 0.8, 1.0}},
                        {"metallicFactor", 0.0},
                        {"roughnessFactor", 1.0}}}};

ShadedSample trace_pixel(const Tracer& tracer, double x, double y, int w, int h) {
  TraceStats stats;
  return tracer.trace(tracer.camera().ray(x, y, w, h), &stats);
}

void expect_color_near(const glm::vec3& got, const glm::dvec3& want, double tolerance) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], tolerance) << "channel " << c;
}

TEST(GltfContentTracerTest, ASceneWithoutLightsRendersUnderTheDefaultLighting) {
  // The box and, beside it, a triangle without material or normals (like AnimatedTriangle).
  TempFolder dir;
  GltfContent g = box(kPurple);
  const int triangle = g.add_mesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  g.set_roots({0, g.add_node({{"mesh", triangle}, {"translation", {1.0, -0.5, 0.5}}})});
  g.write(dir / "unlit.gltf");
  const Scene scene = load_gltf(dir / "unlit.gltf");
  Tracer tracer(scene);
  tracer.set_time(0.0);

  // The default camera looks down -Z, so it sees the box's +Z face (normal (0, 0, 1) in the
  // camera's frame too) head on.
  const int kSize = 48;
  glm::dvec2 face_center;
  ASSERT_TRUE(tracer.camera().project({0.0, 0.0, 0.5}, kSize, kSize, &face_center, nullptr));
  const ShadedSample face = trace_pixel(tracer, face_center.x, face_center.y, kSize, kSize);
  ASSERT_TRUE(face.hit);
  EXPECT_NEAR(face.position.z, 0.5f, 1e-4f);
  expect_color_near(face.color,
                    lambert_under_default_light({0.8, 0.4, 0.8}, glm::dvec3(0.0, 0.0, 1.0)), 1e-4);

  // Every pixel that sees a surface is lit; every other one is the background, as before.
  int hits = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const ShadedSample s = trace_pixel(tracer, x + 0.5, y + 0.5, kSize, kSize);
      if (s.hit) {
        ++hits;
        EXPECT_GT(luminance(s.color), 0.05f) << "pixel " << x << "," << y;
      } else {
        EXPECT_EQ(s.color, scene.background) << "pixel " << x << "," << y;
      }
    }
  }
  EXPECT_GT(hits, kSize * kSize / 10);
}

// Under the default lighting the sky is the background too, so a polished metal reflects it as
// a rough one reflects the ambient sky: the box's +Z face as a mirror (roughness 0) shows
// F0 x the sky of the reflection ray leaving the scene, plus the headlight's highlight, which
// is the same with a file's black background (afr_background), where the reflection finds
// black.
TEST(GltfContentTracerTest, AMirrorReflectsTheDefaultSky) {
  TempFolder dir;
  const json mirror = {{"pbrMetallicRoughness",
                        {{"baseColorFactor", {0.9, 0.6, 0.3, 1.0}},
                         {"metallicFactor", 1.0},
                         {"roughnessFactor", 0.0}}}};
  box(mirror).write(dir / "sky.gltf");
  GltfContent black = box(mirror);
  black.doc()["scenes"][0]["extras"]["afr_background"] = {0.0, 0.0, 0.0};
  black.write(dir / "black.gltf");
  const Scene sky_scene = load_gltf(dir / "sky.gltf");
  const Scene black_scene = load_gltf(dir / "black.gltf");
  ASSERT_EQ(sky_scene.background, glm::vec3(float(kSky)));
  Tracer sky(sky_scene), dark(black_scene);
  const int kSize = 48;
  glm::dvec2 face;
  ASSERT_TRUE(sky.camera().project({0.1, 0.15, 0.5}, kSize, kSize, &face, nullptr));
  const ShadedSample with_sky = trace_pixel(sky, face.x, face.y, kSize, kSize);
  const ShadedSample without = trace_pixel(dark, face.x, face.y, kSize, kSize);
  ASSERT_TRUE(with_sky.hit && without.hit);
  // The reflection ray leaves the box (nothing else is there): Schlick's Fresnel of the metal's
  // color at that angle, times the sky.
  const glm::dvec3 d = glm::normalize(glm::dvec3(with_sky.position) - sky.camera().eye);
  const double cos_v = -d.z;  // the face's normal is +Z
  for (int c = 0; c < 3; ++c) {
    const double f0 = mirror["pbrMetallicRoughness"]["baseColorFactor"][c].get<double>();
    const double fresnel = f0 + (1.0 - f0) * std::pow(1.0 - cos_v, 5.0);
    EXPECT_NEAR(with_sky.color[c] - without.color[c], fresnel * kSky, 2e-3) << "channel " << c;
  }
  // A ray that misses shows the sky as the background.
  EXPECT_EQ(trace_pixel(sky, 0.5, 0.5, kSize, kSize).color, glm::vec3(float(kSky)));
}

TEST(GltfContentTracerTest, TheHeadlightFollowsAnAnimatedCamera) {
  // A rig node turns a quarter about +Y in 1 s and carries the camera 4 units out: at 0 s the
  // camera looks at the box's +Z face, at 1 s at its +X face. A light fixed in the world would
  // light the two faces differently; the headlight lights both as the same face.
  TempFolder dir;
  GltfContent g = box(kPurple);
  g.doc()["cameras"] =
      json::array({{{"type", "perspective"}, {"perspective", {{"yfov", 0.6}, {"znear", 0.1}}}}});
  const int camera = g.add_node({{"camera", 0}, {"translation", {0, 0, 4}}});
  const int rig = g.add_node({{"children", {camera}}});
  g.set_roots({0, rig});
  const float h = float(std::sqrt(0.5));
  const int input = g.add_floats({0.0f, 1.0f}, 1);
  const int output = g.add_floats({0, 0, 0, 1, 0, h, 0, h}, 4);
  g.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", rig}, {"path", "rotation"}}}}}},
        {"samplers", {{{"input", input}, {"output", output}}}}}});
  g.write(dir / "orbit.gltf");
  const Scene scene = load_gltf(dir / "orbit.gltf");
  Tracer tracer(scene);

  const glm::dvec3 want = lambert_under_default_light({0.8, 0.4, 0.8}, glm::dvec3(0, 0, 1));
  for (double t : {0.0, 1.0}) {
    SCOPED_TRACE(t);
    tracer.set_time(t);
    const ShadedSample s = trace_pixel(tracer, 16.0, 16.0, 32, 32);
    ASSERT_TRUE(s.hit);
    const glm::dvec3 face = t == 0.0 ? glm::dvec3(0, 0, 0.5) : glm::dvec3(0.5, 0, 0);
    EXPECT_NEAR(glm::dot(glm::dvec3(s.position), glm::normalize(face)), 0.5, 1e-4);
    expect_color_near(s.color, want, 1e-4);
  }
}

TEST(GltfContentTracerTest, TheHeadlightFollowsASteeredView) {
  // A sampler whose camera comes from the display (Tracer::set_view) looks at the box's +X
  // face from (4, 0, 0): the headlight comes with it and lights that face head on.
  TempFolder dir;
  box(kPurple).write(dir / "box.gltf");
  Tracer tracer(load_gltf(dir / "box.gltf"));
  tracer.set_time(0.0);
  const Camera view = Camera::look_at({4, 0, 0}, {0, 0, 0}, {0, 1, 0}, 0.6, 0.1);
  tracer.set_view(view);
  TraceStats stats;
  const ShadedSample s = tracer.trace(view.ray(16.0, 16.0, 32, 32), &stats);
  ASSERT_TRUE(s.hit);
  EXPECT_NEAR(s.position.x, 0.5f, 1e-4f);
  expect_color_near(s.color, lambert_under_default_light({0.8, 0.4, 0.8}, glm::dvec3(0, 0, 1)),
                    1e-4);
  // The next set_time puts it back on the scene's camera, which sees that face edge-on.
  tracer.set_time(0.0);
  const ShadedSample back = tracer.trace(view.ray(16.0, 16.0, 32, 32), &stats);
  const glm::dvec3 side_normal_in_scene_camera(1.0, 0.0, 0.0);
  expect_color_near(
      back.color, lambert_under_default_light({0.8, 0.4, 0.8}, side_normal_in_scene_camera), 1e-4);
}

TEST(GltfContentTracerTest, EmissiveStrengthScalesTheTracedEmission) {
  // A black, rough, non-metallic box reflects nothing: what it shows is its emission alone.
  TempFolder dir;
  GltfContent g =
      box({{"pbrMetallicRoughness",
            {{"baseColorFactor", {0.0, 0.0, 0.0, 1.0}},
             {"metallicFactor", 0.0},
             {"roughnessFactor", 1.0}}},
           {"emissiveFactor", {1.0, 0.5, 0.25}},
           {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4.0}}}}}});
  g.doc()["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  g.write(dir / "glowing.gltf");
  Tracer tracer(load_gltf(dir / "glowing.gltf"));
  tracer.set_time(0.0);
  const ShadedSample s = trace_pixel(tracer, 8.0, 8.0, 16, 16);
  ASSERT_TRUE(s.hit);
  expect_color_near(s.color, glm::dvec3(4.0, 2.0, 1.0), 1e-6);
}

TEST(GltfContentTracerTest, TheDefaultCameraShowsAMovingObjectMoving) {
  // The box slides from x = -3 to x = 3 over 2 s; no camera in the file.
  TempFolder dir;
  GltfContent g = box(kPurple);
  g.animate_translation(0, {0.0f, 2.0f}, {-3, 0, 0, 3, 0, 0});
  g.write(dir / "sliding.gltf");
  Tracer tracer(load_gltf(dir / "sliding.gltf"));

  const int kSize = 40;
  auto hit_centroid = [&](double t) {
    tracer.set_time(t);
    glm::dvec2 sum(0.0);
    int n = 0;
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        if (trace_pixel(tracer, x + 0.5, y + 0.5, kSize, kSize).hit) {
          sum += glm::dvec2(x + 0.5, y + 0.5);
          ++n;
        }
      }
    }
    EXPECT_GT(n, 4) << "t = " << t;
    return n > 0 ? sum / double(n) : glm::dvec2(-1.0);
  };
  const glm::dvec2 start = hit_centroid(0.0);
  const Camera at_start = tracer.camera();
  const glm::dvec2 end = hit_centroid(2.0);
  EXPECT_EQ(tracer.camera().eye, at_start.eye);  // one camera for the whole animation
  EXPECT_LT(start.x, 0.3 * kSize);
  EXPECT_GT(end.x, 0.7 * kSize);
  EXPECT_NEAR(start.y, end.y, 0.5);
}

// ---- Animated texture transforms ----

// The unit quad in z = 0 (uvs (0, 0) to (1, 1) along x and y) under an unlit material whose base
// color texture is `image` (written beside the file) read through `info`'s KHR_texture_transform,
// and an animation whose channels `channels` drive it (samplers over keys at 0 s and 1 s).
GltfContent textured_quad(const TempFolder& dir, const DecodedImage& image, const json& info,
                          const json& material_extras, bool nearest) {
  testing::write_png(image, dir / "texture.png");
  GltfContent g;
  g.doc()["images"] = json::array({{{"uri", "texture.png"}}});
  g.doc()["samplers"] = json::array({{{"magFilter", nearest ? 9728 : 9729}}});
  g.doc()["textures"] = json::array({{{"source", 0}, {"sampler", 0}}});
  json material = {{"pbrMetallicRoughness", {{"baseColorTexture", info}}},
                   {"extensions", {{"KHR_materials_unlit", json::object()}}}};
  material.update(material_extras);
  g.doc()["materials"] = json::array({material});
  g.doc()["extensionsUsed"] = {"KHR_materials_unlit", "KHR_texture_transform",
                               "KHR_animation_pointer"};
  const int mesh = g.add_mesh({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}, 0,
                              {0, 0, 1, 0, 1, 1, 0, 1});
  g.set_roots({g.add_node({{"mesh", mesh}})});
  return g;
}

// Animates property `property` ("offset", "rotation", "scale") of the transform of material 0's
// texture `slot` (its JSON pointer below the material) from `from` to `to` over 0 to 1 s
// (LINEAR).
void animate_uv(GltfContent* g, const std::string& property, const std::vector<float>& from,
                const std::vector<float>& to,
                const std::string& slot = "pbrMetallicRoughness/baseColorTexture") {
  std::vector<float> values = from;
  values.insert(values.end(), to.begin(), to.end());
  json& animations = g->doc()["animations"];
  if (animations.is_null())
    animations = {{{"channels", json::array()}, {"samplers", json::array()}}};
  json& a = animations[0];
  a["samplers"].push_back({{"input", g->add_floats({0.0f, 1.0f}, 1)},
                           {"output", g->add_floats(values, int(from.size()))}});
  const std::string pointer =
      "/materials/0/" + slot + "/extensions/KHR_texture_transform/" + property;
  a["channels"].push_back(
      {{"sampler", a["samplers"].size() - 1},
       {"target",
        {{"path", "pointer"},
         {"extensions", {{"KHR_animation_pointer", {{"pointer", pointer}}}}}}}});
}

// Straight down the quad's normal onto (x, y), as a ray of cone `spread` per unit.
ShadedSample trace_onto(const Tracer& tracer, float x, float y, float spread = 0.0f) {
  TraceStats stats;
  return tracer.trace(Ray{{x, y, 2.0f}, {0.0f, 0.0f, -1.0f}, spread, 0.0f}, &stats);
}

// An offset animated by a quarter of the texture moves a strip of four texels by one texel
// (read by hand); back at 0 s it is where it was.
TEST(GltfContentTracerTest, AnAnimatedTextureOffsetMovesTheTextureAcrossTheSurface) {
  TempFolder dir;
  const DecodedImage strip{4, 1, 3, {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255}};
  const glm::vec3 texels[4] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  GltfContent g = textured_quad(dir, strip, {{"index", 0}}, json::object(), true);
  animate_uv(&g, "offset", {0.0f, 0.0f}, {0.25f, 0.0f});
  g.write(dir / "sliding.gltf");
  Tracer tracer(load_gltf(dir / "sliding.gltf"));
  for (const double t : {0.0, 1.0, 0.0}) {
    tracer.set_time(t);
    for (int k = 0; k < 4; ++k) {
      const ShadedSample s = trace_onto(tracer, 0.125f + 0.25f * float(k), 0.5f);
      ASSERT_TRUE(s.hit);
      const glm::vec3 want = texels[(k + (t > 0.0 ? 1 : 0)) % 4];
      expect_color_near(s.color, glm::dvec3(want), 1e-6);
    }
  }
}

// Offset, rotation and scale animated together give at each time the image of the same
// transform written in the file (baked at load), thin rays and wide ones alike (the level of
// detail follows the transformed coordinates).
TEST(GltfContentTracerTest, AnAnimatedTextureTransformShowsWhatTheSameTransformInTheFileShows) {
  TempFolder dir;
  DecodedImage checker{8, 8, 3, {}};
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      checker.data.insert(checker.data.end(),
                          {uint8_t(30 * x), uint8_t(30 * y), uint8_t((x + y) % 2 ? 240 : 20)});
    }
  }
  GltfContent animated = textured_quad(dir, checker, {{"index", 0}}, json::object(), false);
  animate_uv(&animated, "offset", {0.0f, 0.0f}, {0.4f, -0.2f});
  animate_uv(&animated, "rotation", {0.0f}, {1.2f});
  animate_uv(&animated, "scale", {1.0f, 1.0f}, {3.0f, 0.5f});
  animated.write(dir / "animated.gltf");
  Tracer tracer(load_gltf(dir / "animated.gltf"));
  for (const float t : {0.0f, 0.3f, 1.0f}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    const json transform = {{"offset", {0.4f * t, -0.2f * t}},
                            {"rotation", 1.2f * t},
                            {"scale", {1.0f + 2.0f * t, 1.0f - 0.5f * t}}};
    GltfContent fixed = textured_quad(
        dir, checker, {{"index", 0}, {"extensions", {{"KHR_texture_transform", transform}}}},
        json::object(), false);
    fixed.write(dir / "fixed.gltf");
    const Tracer baked(load_gltf(dir / "fixed.gltf"));
    tracer.set_time(t);
    for (const float spread : {0.0f, 0.05f}) {
      for (int i = 0; i < 25; ++i) {
        const float x = 0.1f + 0.2f * float(i % 5), y = 0.1f + 0.2f * float(i / 5);
        const ShadedSample want = trace_onto(baked, x, y, spread);
        expect_color_near(trace_onto(tracer, x, y, spread).color, glm::dvec3(want.color), 1e-4);
      }
    }
  }
  // The transform does change the image (the comparison above could not pass by chance).
  tracer.set_time(0.0);
  const glm::vec3 before = trace_onto(tracer, 0.3f, 0.7f).color;
  tracer.set_time(1.0);
  EXPECT_GT(glm::length(trace_onto(tracer, 0.3f, 0.7f).color - before), 0.05f);
}

// alphaMode MASK tests the opacity through the animated transform too: the cut-out half of the
// texture slides over the point, and rays pass there.
TEST(GltfContentTracerTest, AnAnimatedTextureTransformMovesAMasksCutOut) {
  TempFolder dir;
  const DecodedImage half{2, 1, 4, {255, 0, 0, 255, 0, 0, 255, 0}};  // opaque red, clear blue
  GltfContent g =
      textured_quad(dir, half, {{"index", 0}}, {{"alphaMode", "MASK"}}, /*nearest=*/true);
  animate_uv(&g, "offset", {0.0f, 0.0f}, {0.5f, 0.0f});
  g.write(dir / "mask.gltf");
  Tracer tracer(load_gltf(dir / "mask.gltf"));
  EXPECT_TRUE(trace_onto(tracer, 0.25f, 0.5f).hit);
  EXPECT_FALSE(trace_onto(tracer, 0.75f, 0.5f).hit);
  tracer.set_time(1.0);
  EXPECT_FALSE(trace_onto(tracer, 0.25f, 0.5f).hit);
  const ShadedSample moved = trace_onto(tracer, 0.75f, 0.5f);
  EXPECT_TRUE(moved.hit);
  expect_color_near(moved.color, {1.0, 0.0, 0.0}, 1e-6);
}

// A normal texture's tangent frame follows its coordinates through an animated transform as
// through the same transform in the file: the quad's tangents are generated from the normal
// texture's coordinates, so turning and stretching them turns the tilt its one texel asks for
// (which a uniform texture's texel alone would not show). With TANGENT in the file, neither
// frame follows the transform.
TEST(GltfContentTracerTest, AnAnimatedNormalTextureTransformTurnsItsTangentFrame) {
  TempFolder dir;
  testing::write_png(DecodedImage{1, 1, 3, {230, 90, 170}}, dir / "normal.png");  // tilted
  const auto quad = [&](const json& transform, bool file_tangents) {
    GltfContent g;
    g.doc()["images"] = json::array({{{"uri", "normal.png"}}});
    g.doc()["textures"] = json::array({{{"source", 0}}});
    json normal = {{"index", 0}};
    if (!transform.is_null()) normal["extensions"]["KHR_texture_transform"] = transform;
    g.doc()["materials"] = json::array(
        {{{"normalTexture", normal},
          {"pbrMetallicRoughness", {{"metallicFactor", 0.0}, {"roughnessFactor", 1.0}}}}});
    g.doc()["extensionsUsed"] = {"KHR_texture_transform", "KHR_animation_pointer"};
    const int mesh = g.add_mesh({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}, 0,
                                {0, 0, 1, 0, 1, 1, 0, 1});
    if (file_tangents) {
      g.doc()["meshes"][size_t(mesh)]["primitives"][0]["attributes"]["TANGENT"] =
          g.add_floats({1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1}, 4);
    }
    g.set_roots({g.add_node({{"mesh", mesh}})});
    return g;
  };
  for (const bool file_tangents : {false, true}) {
    SCOPED_TRACE(file_tangents ? "TANGENT in the file" : "tangents generated");
    GltfContent animated = quad(nullptr, file_tangents);
    animate_uv(&animated, "offset", {0.0f, 0.0f}, {0.3f, 0.1f}, "normalTexture");
    animate_uv(&animated, "rotation", {0.0f}, {2.0f}, "normalTexture");
    animate_uv(&animated, "scale", {1.0f, 1.0f}, {2.0f, -0.5f}, "normalTexture");
    animated.write(dir / "animated.gltf");
    Tracer tracer(load_gltf(dir / "animated.gltf"));
    for (const float t : {0.0f, 0.4f, 1.0f}) {
      SCOPED_TRACE("t = " + std::to_string(t));
      const json transform = {{"offset", {0.3f * t, 0.1f * t}},
                              {"rotation", 2.0f * t},
                              {"scale", {1.0f + t, 1.0f - 1.5f * t}}};
      quad(transform, file_tangents).write(dir / "fixed.gltf");
      const Tracer baked(load_gltf(dir / "fixed.gltf"));
      tracer.set_time(t);
      for (const glm::vec2 at : {glm::vec2(0.2f, 0.3f), glm::vec2(0.7f, 0.6f)}) {
        const ShadedSample want = trace_onto(baked, at.x, at.y);
        ASSERT_TRUE(want.hit);
        expect_color_near(trace_onto(tracer, at.x, at.y).color, glm::dvec3(want.color), 1e-4);
      }
    }
    // The generated frame turns with the transform, so the shading changes; the file's stays.
    tracer.set_time(0.0);
    const glm::vec3 before = trace_onto(tracer, 0.5f, 0.5f).color;
    tracer.set_time(1.0);
    const float change = glm::length(trace_onto(tracer, 0.5f, 0.5f).color - before);
    if (file_tangents) {
      EXPECT_LT(change, 1e-5f);
    } else {
      EXPECT_GT(change, 0.05f);
    }
  }
}

// ---- Animated material extensions ----

// A material extension's factor that KHR_animation_pointer drives, from one value to another.
struct AnimatedFactor {
  std::string extension, property;
  std::vector<float> from, to;
};

// Builds the scene `make_scene` makes around material 0 twice: once with `factors` animated
// by KHR_animation_pointer over 1 s from their `from` to their `to` values (on `base`), and at
// each of three times once more with the factors written in the file as they stand then. Each
// time's image must match the file's, pixel for pixel, and the image must change over the
// animation.
void expect_animated_factors_shade_as_in_the_file(
    const std::vector<AnimatedFactor>& factors, const json& base,
    const std::function<GltfContent(const json&)>& make_scene) {
  // The material with each factor at s in [0, 1] of the way from `from` to `to`.
  const auto material = [&](float s) {
    json m = base;
    for (const AnimatedFactor& f : factors) {
      json value = json::array();
      for (size_t k = 0; k < f.from.size(); ++k)
        value.push_back(f.from[k] + s * (f.to[k] - f.from[k]));
      m["extensions"][f.extension][f.property] = f.from.size() == 1 ? value[0] : value;
    }
    return m;
  };
  json used = {"KHR_animation_pointer"};
  for (const AnimatedFactor& f : factors) {
    if (std::find(used.begin(), used.end(), f.extension) == used.end()) used.push_back(f.extension);
  }
  const auto with_used = [&](GltfContent g) {
    for (const json& e : used) {
      if (!g.doc().contains("extensionsUsed") ||
          std::find(g.doc()["extensionsUsed"].begin(), g.doc()["extensionsUsed"].end(), e) ==
              g.doc()["extensionsUsed"].end()) {
        g.doc()["extensionsUsed"].push_back(e);
      }
    }
    return g;
  };
  TempFolder dir;
  GltfContent animated = with_used(make_scene(material(0.0f)));
  json a = {{"channels", json::array()}, {"samplers", json::array()}};
  const int times = animated.add_floats({0.0f, 1.0f}, 1);
  for (const AnimatedFactor& f : factors) {
    std::vector<float> keys = f.from;
    keys.insert(keys.end(), f.to.begin(), f.to.end());
    a["samplers"].push_back(
        {{"input", times}, {"output", animated.add_floats(keys, int(f.from.size()))}});
    const std::string pointer = "/materials/0/extensions/" + f.extension + "/" + f.property;
    a["channels"].push_back(
        {{"sampler", a["samplers"].size() - 1},
         {"target",
          {{"path", "pointer"},
           {"extensions", {{"KHR_animation_pointer", {{"pointer", pointer}}}}}}}});
  }
  animated.doc()["animations"] = json::array({a});
  animated.write(dir / "animated.gltf");
  GltfLoadReport report;
  Tracer tracer(load_gltf(dir / "animated.gltf", &report));
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  const int kSize = 16;
  std::vector<glm::vec3> first;
  for (const float t : {0.0f, 0.4f, 1.0f}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    with_used(make_scene(material(t))).write(dir / "fixed.gltf");
    const Tracer baked(load_gltf(dir / "fixed.gltf"));
    tracer.set_time(t);
    double change = 0.0;
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const ShadedSample got = trace_pixel(tracer, x + 0.5, y + 0.5, kSize, kSize);
        const ShadedSample want = trace_pixel(baked, x + 0.5, y + 0.5, kSize, kSize);
        ASSERT_EQ(got.hit, want.hit);
        expect_color_near(got.color, glm::dvec3(want.color), 1e-4);
        if (t == 0.0f) first.push_back(got.color);
        change += glm::length(got.color - first[size_t(y * kSize + x)]);
      }
    }
    if (t == 1.0f) {
      EXPECT_GT(change, 1.0);  // the animation shows
    }
  }
}

// The material extensions' factors that KHR_animation_pointer drives (clearcoat, sheen,
// specular, iridescence, anisotropy) shade at each time as the same factors written in the
// file do, and the image does change over the animation.
TEST(GltfContentTracerTest, AnimatedMaterialExtensionFactorsShadeAsTheSameFactorsInTheFile) {
  expect_animated_factors_shade_as_in_the_file(
      {
          {"KHR_materials_clearcoat", "clearcoatFactor", {0.0f}, {1.0f}},
          {"KHR_materials_clearcoat", "clearcoatRoughnessFactor", {0.1f}, {0.6f}},
          {"KHR_materials_sheen", "sheenColorFactor", {0.0f, 0.0f, 0.0f}, {0.9f, 0.5f, 0.2f}},
          {"KHR_materials_sheen", "sheenRoughnessFactor", {0.2f}, {0.8f}},
          {"KHR_materials_specular", "specularFactor", {1.0f}, {0.3f}},
          {"KHR_materials_specular", "specularColorFactor", {1.0f, 1.0f, 1.0f}, {0.2f, 1.5f, 0.7f}},
          {"KHR_materials_iridescence", "iridescenceFactor", {0.0f}, {1.0f}},
          {"KHR_materials_iridescence", "iridescenceIor", {1.3f}, {1.8f}},
          {"KHR_materials_iridescence", "iridescenceThicknessMinimum", {100.0f}, {300.0f}},
          {"KHR_materials_iridescence", "iridescenceThicknessMaximum", {400.0f}, {700.0f}},
          {"KHR_materials_anisotropy", "anisotropyStrength", {0.0f}, {0.8f}},
          {"KHR_materials_anisotropy", "anisotropyRotation", {0.0f}, {1.0f}},
      },
      {{"pbrMetallicRoughness",
        {{"baseColorFactor", {0.6, 0.3, 0.2, 1.0}},
         {"metallicFactor", 0.0},
         {"roughnessFactor", 0.5}}}},
      box);
}

// Transmission, ior, volume and dispersion driven by KHR_animation_pointer: a box that turns
// from opaque (transmission 0) into absorbing, dispersive glass, in front of a lit wall it casts
// its shadow on. At each time the camera's rays through it and the shadow rays to the wall see
// what the same factors written in the file give: its geometry lets shadow rays through only
// while it is glass, though it was not glass when the tracer was built.
TEST(GltfContentTracerTest, AnimatedTransmissionIorAndVolumeShadeAsTheSameFactorsInTheFile) {
  const auto glass_before_a_wall = [](const json& glass) {
    GltfContent g;
    g.doc()["materials"] = json::array({glass, kPurple});
    const int wall =
        g.add_mesh({-3, -3, -1.5f, 3, -3, -1.5f, 3, 3, -1.5f, -3, 3, -1.5f}, {0, 1, 2, 0, 2, 3}, 1);
    g.doc()["extensions"]["KHR_lights_punctual"]["lights"] =
        json::array({{{"type", "point"}, {"intensity", 20.0}}});
    g.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
    g.set_roots({g.add_node({{"mesh", g.add_box(0.5f, 0)}}), g.add_node({{"mesh", wall}}),
                 g.add_node({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}},
                             {"translation", {1.2, 0.9, 2.5}}})});
    return g;
  };
  expect_animated_factors_shade_as_in_the_file(
      {
          {"KHR_materials_transmission", "transmissionFactor", {0.0f}, {1.0f}},
          {"KHR_materials_ior", "ior", {1.5f}, {1.2f}},
          {"KHR_materials_volume", "thicknessFactor", {0.0f}, {1.0f}},
          {"KHR_materials_volume", "attenuationDistance", {2.0f}, {0.5f}},
          {"KHR_materials_volume", "attenuationColor", {1.0f, 1.0f, 1.0f}, {0.8f, 0.5f, 0.2f}},
          {"KHR_materials_dispersion", "dispersion", {0.0f}, {1.0f}},
      },
      {{"pbrMetallicRoughness",
        {{"baseColorFactor", {0.9, 0.9, 0.9, 1.0}},
         {"metallicFactor", 0.0},
         {"roughnessFactor", 0.2}}}},
      glass_before_a_wall);
}

// KHR_materials_diffuse_transmission driven by KHR_animation_pointer: a screen between the
// camera and a light behind it lets more and more of the light through, tinted by the animated
// color, shading at each time as the same factors written in the file do; so does a floor on
// the camera's side, which the light reaches through the screen (its shadow rays pass the
// screen dimmed by what it transmits, although the screen transmits nothing at the start).
TEST(GltfContentTracerTest, AnimatedDiffuseTransmissionShadesAsTheSameFactorsInTheFile) {
  const auto screen_before_a_light = [](const json& screen) {
    GltfContent g;
    const json floor_material = {
        {"pbrMetallicRoughness",
         {{"baseColorFactor", {0.8, 0.8, 0.8, 1.0}}, {"metallicFactor", 0.0}}}};
    g.doc()["materials"] = json::array({screen, floor_material});
    const int wall =
        g.add_mesh({-3, -3, -1.5f, 3, -3, -1.5f, 3, 3, -1.5f, -3, 3, -1.5f}, {0, 1, 2, 0, 2, 3}, 0);
    const int floor =
        g.add_mesh({-3, -2, 1.5f, 3, -2, 1.5f, 3, -2, -1.4f, -3, -2, -1.4f}, {0, 1, 2, 0, 2, 3}, 1);
    g.doc()["extensions"]["KHR_lights_punctual"]["lights"] =
        json::array({{{"type", "point"}, {"intensity", 20.0}}});
    g.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
    g.set_roots({g.add_node({{"mesh", wall}}), g.add_node({{"mesh", floor}}),
                 g.add_node({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}},
                             {"translation", {0.4, 0.3, -3.0}}})});
    return g;
  };
  expect_animated_factors_shade_as_in_the_file(
      {
          {"KHR_materials_diffuse_transmission", "diffuseTransmissionFactor", {0.0f}, {1.0f}},
          {"KHR_materials_diffuse_transmission",
           "diffuseTransmissionColorFactor",
           {1.0f, 1.0f, 1.0f},
           {0.9f, 0.5f, 0.2f}},
      },
      {{"pbrMetallicRoughness",
        {{"baseColorFactor", {0.6, 0.3, 0.2, 1.0}},
         {"metallicFactor", 0.0},
         {"roughnessFactor", 0.5}}}},
      screen_before_a_light);
}

// ---- Animated visibility ----

// KHR_node_visibility driven by KHR_animation_pointer: the morphed quad (deformed geometry) shows
// at 0 s and 2 s and hides at 1 s; a box, its child box and the child's point light hide at
// 0 s and show from 1 s. While the light is hidden the quad gets none of its light.
TEST(GltfContentTracerTest, AnAnimatedVisibilityShowsAndHidesNodesTheirChildrenAndLights) {
  TempFolder dir;
  GltfContent g = testing::MorphedQuad::make(Interpolation::kLinear);  // node 0, x 2 to 4
  const int box = g.add_box(0.5f);
  const int light = g.add_node({{"translation", {5.0, 1.0, 3.0}},
                                {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  const int child = g.add_node({{"mesh", box}, {"translation", {0.0, 3.0, 0.0}}});
  const int parent =
      g.add_node({{"mesh", box}, {"translation", {-2.0, 0.0, 0.0}}, {"children", {child, light}}});
  g.set_roots({0, parent});
  g.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}, {"intensity", 40}}};
  g.doc()["extensionsUsed"] = {"KHR_lights_punctual", "KHR_node_visibility",
                               "KHR_animation_pointer"};
  json& a = g.doc()["animations"][0];
  const int times = g.add_floats({0.0f, 1.0f, 2.0f}, 1);
  const auto blink = [&](int node, std::vector<float> keys) {
    a["samplers"].push_back(
        {{"input", times}, {"output", g.add_floats(keys, 1)}, {"interpolation", "STEP"}});
    a["channels"].push_back(
        {{"sampler", a["samplers"].size() - 1},
         {"target",
          {{"path", "pointer"},
           {"extensions",
            {{"KHR_animation_pointer",
              {{"pointer", "/nodes/" + std::to_string(node) +
                               "/extensions/KHR_node_visibility/visible"}}}}}}}});
  };
  blink(0, {1, 0, 1});
  blink(parent, {0, 1, 1});
  g.write(dir / "blink.gltf");
  Tracer tracer(load_gltf(dir / "blink.gltf"));

  const auto onto = [&](float x, float y) {
    TraceStats stats;
    return tracer.trace(Ray{{x, y, 10.0f}, {0.0f, 0.0f, -1.0f}}, &stats);
  };
  struct When {
    double t;
    bool quad, boxes;
  };
  for (const When w : {When{0.0, true, false}, When{0.5, true, false}, When{1.0, false, true},
                       When{2.0, true, true}, When{0.0, true, false}}) {
    SCOPED_TRACE("t = " + std::to_string(w.t));
    tracer.set_time(w.t);
    const ShadedSample quad = onto(3.0f, 1.0f);
    EXPECT_EQ(quad.hit, w.quad);
    EXPECT_EQ(onto(-2.0f, 0.0f).hit, w.boxes);
    EXPECT_EQ(onto(-2.0f, 3.0f).hit, w.boxes);
    if (quad.hit) {  // lit only while the light's node shows
      if (w.boxes) {
        EXPECT_GT(quad.color.g, 0.05f);
      } else {
        EXPECT_LT(quad.color.g, 1e-6f);
      }
    }
  }
}

}  // namespace
}  // namespace afr
