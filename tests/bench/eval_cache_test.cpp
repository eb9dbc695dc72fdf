// The ideal-frame cache: its key changes with everything that changes an ideal frame and with
// nothing else, and a cached frame is the rendered frame, bit for bit.
#include <afr/common/builtin_scene.h>
#include <afr/eval/ideal_cache.h>
#include <afr/eval/scene_setup.h>

#include "eval_test_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <set>

namespace afr::eval {
namespace {

TEST(IdealCacheTest, KeyChangesWithSceneTimeSizeSppAndOptionsOnly) {
  IdealRenderOptions o;
  o.width = 256;
  o.height = 128;
  o.strata = 4;
  o.time = 8.5 + 7.0 / 60.0;
  const TracerOptions t;
  const std::string key = ideal_cache_key(0x1234, o, t);
  EXPECT_EQ(key.rfind("0000000000001234-256x128-spp16-t8.616666666666667-o", 0), 0u) << key;

  std::set<std::string> keys{key};
  const auto differs = [&](IdealRenderOptions changed, TracerOptions tracer, uint64_t scene) {
    return keys.insert(ideal_cache_key(scene, changed, tracer)).second;
  };
  IdealRenderOptions c = o;
  c.time = std::nextafter(o.time, 100.0);  // one ulp later is another frame
  EXPECT_TRUE(differs(c, t, 0x1234));
  EXPECT_TRUE(differs(o, t, 0x1235));
  c = o;
  c.width = 128;
  EXPECT_TRUE(differs(c, t, 0x1234));
  c = o;
  c.height = 256;
  EXPECT_TRUE(differs(c, t, 0x1234));
  c = o;
  c.strata = 3;
  EXPECT_TRUE(differs(c, t, 0x1234));
  c = o;
  c.seed = 2;
  EXPECT_TRUE(differs(c, t, 0x1234));
  c = o;
  c.filter_alpha = 3.0;
  EXPECT_TRUE(differs(c, t, 0x1234));
  TracerOptions tc;
  tc.max_mirror_depth = 1;
  EXPECT_TRUE(differs(o, tc, 0x1234));
  // Threads and the packet path change nothing in the picture, so not the key either.
  c = o;
  c.threads = 7;
  EXPECT_FALSE(differs(c, t, 0x1234));
  tc = t;
  tc.packet_crosshair = !t.packet_crosshair;
  EXPECT_FALSE(differs(o, tc, 0x1234));
}

TEST(IdealCacheTest, SceneHashSeesContentNotNames) {
  const Scene a = make_builtin_scene(), b = make_builtin_scene();
  const uint64_t h = render_fingerprint(a);
  EXPECT_EQ(h, render_fingerprint(b));
  Scene renamed = make_builtin_scene();
  for (Node& n : renamed.nodes) n.name += " (renamed)";
  renamed.source = "elsewhere.gltf";
  EXPECT_EQ(render_fingerprint(renamed), h);

  Scene moved = make_builtin_scene();
  moved.meshes[0].primitives[0].positions[0].x += 1e-3f;
  EXPECT_NE(render_fingerprint(moved), h);
  Scene recolored = make_builtin_scene();
  recolored.materials[0].base_color_factor.g *= 0.5f;
  EXPECT_NE(render_fingerprint(recolored), h);
  Scene retimed = make_builtin_scene();
  retimed.channels[0].times.back() += 0.5;
  EXPECT_NE(render_fingerprint(retimed), h);
  Scene relit = make_builtin_scene();
  relit.lights[0].intensity *= 2.0f;
  EXPECT_NE(render_fingerprint(relit), h);
  // Fields that add bytes only where a scene has them: setting one (`add`) changes the hash,
  // and so does changing it again (`change`).
  auto expect_seen = [&](const char* what, const std::function<void(Scene*)>& add,
                         const std::function<void(Scene*)>& change) {
    Scene s = make_builtin_scene();
    add(&s);
    const uint64_t added = render_fingerprint(s);
    EXPECT_NE(added, h) << what;
    change(&s);
    EXPECT_NE(render_fingerprint(s), added) << what;
  };
  expect_seen(
      "vertex colors",
      [](Scene* s) {
        Primitive& p = s->meshes[0].primitives[0];
        p.colors.assign(p.positions.size(), glm::vec3(1.0f));
      },
      [](Scene* s) { s->meshes[0].primitives[0].colors[0].r = 0.5f; });
  expect_seen(
      "glass", [](Scene* s) { s->materials[0].transmission = 0.5f; },
      [](Scene* s) { s->materials[0].ior = 1.33f; });
  expect_seen(
      "alpha mask", [](Scene* s) { s->materials[0].alpha_mode = Material::AlphaMode::kMask; },
      [](Scene* s) { s->materials[0].alpha_cutoff = 0.25f; });
  expect_seen(
      "texture alpha",
      [](Scene* s) { s->textures[0].alpha.assign(s->textures[0].texels.size(), 1.0f); },
      [](Scene* s) { s->textures[0].alpha[0] = 0.5f; });
  expect_seen(
      "unlit", [](Scene* s) { s->materials[0].unlit = true; },
      [](Scene* s) { s->materials[0].base_color_factor.r *= 0.5f; });
  expect_seen(
      "normal texture", [](Scene* s) { s->materials[0].normal_texture = 0; },
      [](Scene* s) { s->materials[0].normal_scale = 0.5f; });
  expect_seen(
      "vertex alpha",
      [](Scene* s) {
        Primitive& p = s->meshes[0].primitives[0];
        p.color_alpha.assign(p.positions.size(), 1.0f);
      },
      [](Scene* s) { s->meshes[0].primitives[0].color_alpha[0] = 0.5f; });
  expect_seen(
      "tangents",
      [](Scene* s) {
        Primitive& p = s->meshes[0].primitives[0];
        p.tangents.assign(p.positions.size(), glm::vec4(1, 0, 0, 1));
      },
      [](Scene* s) { s->meshes[0].primitives[0].tangents[0].w = -1.0f; });
  expect_seen(
      "texture coordinate sets",
      [](Scene* s) {
        Primitive& p = s->meshes[0].primitives[0];
        p.more_uvs = {p.uvs};
        s->materials[0].uv_set.occlusion = 1;
      },
      [](Scene* s) { s->meshes[0].primitives[0].more_uvs[0][0].x += 0.5f; });
  expect_seen(
      "specular", [](Scene* s) { s->materials[0].has_specular_extension = true; },
      [](Scene* s) { s->materials[0].specular = 0.5f; });
  expect_seen(
      "specular glossiness",
      [](Scene* s) {
        s->materials[0].has_specular_extension = true;
        s->materials[0].specular_glossiness = true;
      },
      [](Scene* s) { s->materials[0].glossiness_texture = 0; });
  expect_seen(
      "iridescence", [](Scene* s) { s->materials[0].iridescence = 1.0f; },
      [](Scene* s) { s->materials[0].iridescence_thickness_max = 300.0f; });
  expect_seen(
      "clearcoat", [](Scene* s) { s->materials[0].clearcoat = 1.0f; },
      [](Scene* s) { s->materials[0].clearcoat_roughness = 0.5f; });
  expect_seen(
      "extension textures", [](Scene* s) { s->materials[0].clearcoat_texture = 0; },
      [](Scene* s) { s->materials[0].clearcoat_normal_scale = 0.5f; });
  expect_seen(
      "extension texture sets",
      [](Scene* s) {
        Primitive& p = s->meshes[0].primitives[0];
        p.more_uvs = {p.uvs};
        s->materials[0].specular_texture = 0;
      },
      [](Scene* s) { s->materials[0].uv_set.specular = 1; });
  expect_seen(
      "sheen", [](Scene* s) { s->materials[0].sheen_color = glm::vec3(1.0f); },
      [](Scene* s) { s->materials[0].sheen_roughness = 0.5f; });
  expect_seen(
      "anisotropy", [](Scene* s) { s->materials[0].anisotropy = 0.5f; },
      [](Scene* s) { s->materials[0].anisotropy_rotation = 1.0f; });
  expect_seen(
      "volume", [](Scene* s) { s->materials[0].thickness = 1.0f; },
      [](Scene* s) { s->materials[0].attenuation_distance = 2.0f; });
  expect_seen(
      "dispersion",
      [](Scene* s) {
        s->materials[0].thickness = 1.0f;
        s->materials[0].dispersion = 1.0f;
      },
      [](Scene* s) { s->materials[0].dispersion = 2.0f; });
  expect_seen(
      "diffuse transmission", [](Scene* s) { s->materials[0].diffuse_transmission = 0.5f; },
      [](Scene* s) { s->materials[0].diffuse_transmission_color = glm::vec3(0.5f); });
  expect_seen(
      "diffuse transmission texture",
      [](Scene* s) { s->materials[0].diffuse_transmission_texture = 0; },
      [](Scene* s) { s->materials[0].diffuse_transmission_color_texture = 0; });
  expect_seen(
      "ray depth", [](Scene* s) { s->ray_depth = 6; }, [](Scene* s) { s->ray_depth = 0; });
  expect_seen(
      "samplers", [](Scene* s) { s->textures[0].wrap_s = Texture::Wrap::kClampToEdge; },
      [](Scene* s) { s->textures[0].nearest = true; });
  expect_seen(
      "occlusion", [](Scene* s) { s->materials[0].occlusion_texture = 0; },
      [](Scene* s) { s->materials[0].occlusion_strength = 0.5f; });
  expect_seen(
      "orthographic camera", [](Scene* s) { s->cameras[0].ymag = 2.0; },
      [](Scene* s) { s->cameras[0].ymag = 3.0; });
  expect_seen(
      "animated properties",
      [](Scene* s) {
        PropertyChannel p;
        p.property = AnimatedProperty::kLightIntensity;
        p.index = 0;
        p.curve.interpolation = Interpolation::kLinear;
        p.curve.times = {0.0, 1.0};
        p.curve.values = {glm::dvec4(1.0), glm::dvec4(2.0)};
        s->property_channels.push_back(p);
      },
      [](Scene* s) { s->property_channels[0].curve.values[1].x = 3.0; });
  expect_seen(
      "node visibility", [](Scene* s) { s->nodes[0].visible = false; },
      [](Scene* s) {
        PropertyChannel p;
        p.property = AnimatedProperty::kNodeVisible;
        p.index = 0;
        p.curve.times = {0.0};
        p.curve.values = {glm::dvec4(1.0)};
        s->property_channels.push_back(p);
      });
  expect_seen(
      "animated texture transforms", [](Scene* s) { s->materials[0].uv_transforms.resize(1); },
      [](Scene* s) { s->materials[0].uv_transforms[0].rotation = 0.5; });
  expect_seen(
      "the set a texture transform's channel drives",
      [](Scene* s) {
        Material& m = s->materials[0];
        m.uv_transforms.resize(2);
        m.uv_set.emissive = 1;
        PropertyChannel p;
        p.property = AnimatedProperty::kUvRotation;
        p.index = 0;
        p.uv_set = 0;
        p.curve.times = {0.0, 1.0};
        p.curve.values = {glm::dvec4(0.0), glm::dvec4(1.0)};
        s->property_channels.push_back(p);
      },
      [](Scene* s) { s->property_channels[0].uv_set = 1; });
  Scene with_path = make_builtin_scene();
  CameraKey k;
  k.eye = glm::dvec3(0, 1, 5);
  apply_camera_path(CameraPath({k}), &with_path);
  EXPECT_NE(render_fingerprint(with_path), h);
}

TEST(IdealCacheTest, SceneHashSeesSkinsAndMorphTargets) {
  // The built-in scene's first mesh with a morph target lifting it by dz at weight w, skinned
  // (or not) to its own node with inverse bind matrix `ibm`, its weight driven (or not) by a
  // channel from 0 to `key`; with `tangents` != 0, tangents that the target turns by that much.
  auto deformed = [](float dz, float w, bool skinned, double ibm, double key,
                     float tangents = 0.0f) {
    Scene s = make_builtin_scene();
    Primitive& p = s.meshes[0].primitives[0];
    p.targets.push_back({std::vector<glm::vec3>(p.positions.size(), {0.0f, 0.0f, dz}), {}, {}});
    if (tangents != 0.0f) {
      p.tangents.assign(p.positions.size(), glm::vec4(1, 0, 0, 1));
      p.targets.back().tangents.assign(p.positions.size(), glm::vec3(0.0f, tangents, 0.0f));
    }
    s.meshes[0].weights = {w};
    int node = 0;
    while (s.nodes[size_t(node)].mesh != 0) ++node;
    if (skinned) {
      p.joints.assign(p.positions.size(), {0, 0, 0, 0});
      p.joint_weights.assign(p.positions.size(), {1.0f, 0.0f, 0.0f, 0.0f});
      s.skins.push_back({"skin", {node}, {glm::dmat4(ibm)}, -1});
      s.nodes[size_t(node)].skin = 0;
    }
    if (key != 0.0) {
      AnimationChannel c;
      c.node = node;
      c.path = AnimatedPath::kWeights;
      c.times = {0.0, 1.0};
      c.weight_count = 1;
      c.weights = {0.0, key};
      s.channels.push_back(c);
    }
    return render_fingerprint(s);
  };
  const uint64_t plain = render_fingerprint(make_builtin_scene());
  const uint64_t h = deformed(1.0f, 0.5f, false, 1.0, 0.0);
  EXPECT_NE(h, plain);
  EXPECT_EQ(deformed(1.0f, 0.5f, false, 1.0, 0.0), h);
  EXPECT_NE(deformed(2.0f, 0.5f, false, 1.0, 0.0), h);
  EXPECT_NE(deformed(1.0f, 0.25f, false, 1.0, 0.0), h);
  const uint64_t skinned = deformed(1.0f, 0.5f, true, 1.0, 0.0);
  EXPECT_NE(skinned, h);
  EXPECT_NE(deformed(1.0f, 0.5f, true, 2.0, 0.0), skinned);
  const uint64_t animated = deformed(1.0f, 0.5f, false, 1.0, 1.0);
  EXPECT_NE(animated, h);
  EXPECT_NE(deformed(1.0f, 0.5f, false, 1.0, 0.5), animated);
  const uint64_t turned = deformed(1.0f, 0.5f, false, 1.0, 0.0, 1.0f);
  EXPECT_NE(turned, h);
  EXPECT_NE(deformed(1.0f, 0.5f, false, 1.0, 0.0, 0.5f), turned);
}

TEST(IdealCacheTest, CachedFrameIsTheRenderedFrameAndIsRenderedOnce) {
  const Scene scene = testing::sliding_quad_scene(1.0);
  Tracer tracer(scene);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "afr_ideal_cache_test";
  std::filesystem::remove_all(dir);
  IdealCache cache(dir, render_fingerprint(scene));
  IdealRenderOptions o;
  o.width = 24;
  o.height = 16;
  o.strata = 2;
  o.time = 0.75;
  const Image first = cache.frame(tracer, o);
  EXPECT_EQ(cache.stats().misses, 1u);
  EXPECT_TRUE(std::filesystem::is_regular_file(cache.path_of(o, tracer.options())));
  const Image again = cache.frame(tracer, o);
  EXPECT_EQ(cache.stats().hits, 1u);
  EXPECT_EQ(cache.stats().misses, 1u);
  EXPECT_EQ(first.pixels, again.pixels);
  EXPECT_EQ(first.pixels, render_ideal(tracer, o).pixels);
  // Another time is another frame.
  o.time = 0.8;
  cache.frame(tracer, o);
  EXPECT_EQ(cache.stats().misses, 2u);
  // A file of the wrong size under the key is rendered again.
  write_image(Image(3, 3), cache.path_of(o, tracer.options()));
  const Image fixed = cache.frame(tracer, o);
  EXPECT_EQ(fixed.width, 24);
  EXPECT_EQ(cache.stats().misses, 3u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace afr::eval
