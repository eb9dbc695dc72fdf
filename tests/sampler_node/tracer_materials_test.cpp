// Tests of the tracer's materials on small scenes built here (tracer_test_scenes.h): textures,
// normal and tangent frames, alpha modes, the material extensions and mirrors, each against the
// formulas written out by hand or single rays.
#include <afr/common/error.h>
#include <afr/common/random.h>
#include <afr/sampler/tracer.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "tracer_test_scenes.h"

namespace afr::tracer_test {
namespace {

// ---------------------------------------------------------------------------------------------
// Materials

TEST(TracerTest, TextureColorMultipliesBaseColor) {
  Scene s;
  s.ambient = glm::vec3(1.0f);  // ambient light only: color = ambient x base x texture
  Texture tex;
  tex.width = 2;
  tex.height = 2;
  // Row 0 (v < 0.5): red, green; row 1: blue, white.
  tex.texels = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  s.textures.push_back(tex);
  const int mat = add_material(&s, glm::vec3(0.5f, 0.8f, 0.6f), 0.0f, 1.0f);
  s.materials[size_t(mat)].base_color_texture = 0;
  // The square [-1, 1]^2 at z = -2 with uv = ((x + 1) / 2 + 1, (y + 1) / 2 - 2): REPEAT makes
  // that ((x + 1) / 2, (y + 1) / 2).
  Mesh square = quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat);
  for (glm::vec2& uv : square.primitives[0].uvs) uv += glm::vec2(1.0f, -2.0f);
  add_mesh_node(&s, square);
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  // Texel centers, where bilinear filtering returns the texel itself: uv (0.75, 0.25) is
  // texel (1, 0) = green, uv (0.25, 0.75) is texel (0, 1) = blue.
  const ShadedSample green = tracer.trace(Ray{{0.5f, -0.5f, 0.0f}, {0, 0, -1}}, &stats);
  const ShadedSample blue = tracer.trace(Ray{{-0.5f, 0.5f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(green.color, {0.0f, 0.8f, 0.0f}, 1e-5f, "green texel");
  expect_near3(blue.color, {0.0f, 0.0f, 0.6f}, 1e-5f, "blue texel");
}

// COLOR_0 multiplies the base color, interpolated by the hit's barycentrics: (0.5, -0.5) on the
// square below is 0.25 v0 + 0.5 v1 + 0.25 v2 of its first triangle.
TEST(TracerTest, VertexColorsMultiplyBaseColorInterpolatedAcrossTheTriangle) {
  Scene s;
  s.ambient = glm::vec3(1.0f);  // ambient light only: color = ambient x base x vertex color
  const int mat = add_material(&s, glm::vec3(0.5f, 0.8f, 0.6f), 0.0f, 1.0f);
  Mesh square = quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat);
  square.primitives[0].colors = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  add_mesh_node(&s, square);
  // A second square beside it without colors: the base color alone.
  add_mesh_node(&s, quad_mesh({3, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const ShadedSample mixed = tracer.trace(Ray{{0.5f, -0.5f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(mixed.color, {0.125f, 0.4f, 0.15f}, 1e-5f, "interpolated colors");
  const ShadedSample corner = tracer.trace(Ray{{-0.999f, 0.999f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(corner.color, {0.5f, 0.8f, 0.6f}, 1e-2f, "the white corner");
  const ShadedSample plain = tracer.trace(Ray{{4.0f, 0.0f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(plain.color, {0.5f, 0.8f, 0.6f}, 1e-5f, "no vertex colors");
}

// COLOR_0's alpha multiplies a masking material's opacity: a red square of factor alpha 1 whose
// vertex alpha runs from 0 on its left edge to 1 on its right is cut away left of its middle
// (alpha < 0.5) for camera and occlusion rays alike; the same material on a square without
// vertex alpha is whole.
TEST(TracerTest, VertexAlphaCutsAMaskedSurface) {
  Scene s;
  s.ambient = glm::vec3(1.0f);
  const int red = add_material(&s, {1, 0, 0}, 0.0f, 1.0f);
  s.materials[size_t(red)].alpha_mode = Material::AlphaMode::kMask;
  const int green = add_material(&s, {0, 1, 0}, 0.0f, 1.0f);
  Mesh faded = quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, red);
  faded.primitives[0].colors = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  faded.primitives[0].color_alpha = {0.0f, 1.0f, 1.0f, 0.0f};  // v0 and v3 on the left
  add_mesh_node(&s, faded);
  add_mesh_node(&s, quad_mesh({2, -1, -2}, {2, 0, 0}, {0, 2, 0}, red));
  add_mesh_node(&s, quad_mesh({-8, -8, -4}, {16, 0, 0}, {0, 16, 0}, green));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  for (const float y : {-0.7f, 0.0f, 0.7f}) {
    expect_near3(tracer.trace(Ray{{-0.4f, y, 0.0f}, {0, 0, -1}}, &stats).color, {0, 1, 0}, 1e-5f,
                 "left of the middle: cut away");
    expect_near3(tracer.trace(Ray{{0.4f, y, 0.0f}, {0, 0, -1}}, &stats).color, {1, 0, 0}, 1e-5f,
                 "right of the middle: kept");
    EXPECT_FALSE(tracer.occluded({-0.4f, y, 0.0f}, {-0.4f, y, -3.0f}, &stats));
    EXPECT_TRUE(tracer.occluded({0.4f, y, 0.0f}, {0.4f, y, -3.0f}, &stats));
    expect_near3(tracer.trace(Ray{{2.6f, y, 0.0f}, {0, 0, -1}}, &stats).color, {1, 0, 0}, 1e-5f,
                 "no vertex alpha: whole");
  }
}

// A material's metallic-roughness, emissive and occlusion textures decide it at each point: a
// square whose textures hold, in three texels across, (1) a rough dielectric, (2) a polished
// metal (a mirror) and (3) a rough metal, each with its own emission and occlusion, shades at
// each texel's center exactly as a square of a plain material with those values does.
TEST(TracerTest, MaterialTexturesDecideTheMaterialAtEachPoint) {
  struct Point {
    float metallic, roughness;  // texel x factor
    glm::vec3 emissive;         // texel x factor
    float ambient;              // occlusion texel moved toward 1 by 1 - strength
  };
  // Factors: metallic 1, roughness 0.8, emissive (2, 2, 2), occlusion strength 0.5.
  const Point points[3] = {{0.0f, 0.8f * 0.5f, {2.0f, 0.0f, 0.0f}, 1.0f + 0.5f * (0.25f - 1.0f)},
                           {1.0f, 0.0f, {0.0f, 2.0f, 0.0f}, 1.0f},
                           {1.0f, 0.8f, {0.0f, 0.0f, 1.0f}, 1.0f + 0.5f * (0.0f - 1.0f)}};
  // The square [-1, 1]^2 at z = -2 under a point light and ambient light, a wall beside it for
  // the mirror to show; `textured` builds the textured material, else the plain one of point k.
  auto scene_of = [&](bool textured, int k) {
    Scene s;
    s.ambient = glm::vec3(0.3f);
    s.background = glm::vec3(0.1f, 0.2f, 0.4f);
    const glm::vec3 base(0.8f, 0.5f, 0.3f);
    int mat;
    if (textured) {
      mat = add_material(&s, base, 1.0f, 0.8f);
      Material& m = s.materials[size_t(mat)];
      m.emissive = glm::vec3(2.0f);
      m.occlusion_strength = 0.5f;
      Texture mr, em, occ;
      mr.width = em.width = occ.width = 3;
      mr.height = em.height = occ.height = 1;
      mr.texels = {{0.7f, 0.5f, 0.0f}, {0.7f, 0.0f, 1.0f}, {0.7f, 1.0f, 1.0f}};  // red unused
      em.texels = {{1, 0, 0}, {0, 1, 0}, {0, 0, 0.5f}};
      occ.texels = {{0.25f, 1, 1}, {1, 0, 0}, {0, 1, 1}};  // red is the occlusion
      for (Texture* t : {&mr, &em, &occ}) s.textures.push_back(*t);
      m.metallic_roughness_texture = 0;
      m.emissive_texture = 1;
      m.occlusion_texture = 2;
    } else {
      const Point& p = points[k];
      mat = add_material(&s, base, p.metallic, p.roughness);
      s.materials[size_t(mat)].emissive = p.emissive;
      s.materials[size_t(mat)].ambient = base * p.ambient;
    }
    add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
    const int wall = add_material(&s, glm::vec3(0.2f, 0.9f, 0.2f), 0.0f, 1.0f);
    add_mesh_node(&s, quad_mesh({-3, -3, 6}, {0, 0, -12}, {0, 6, 0}, wall));  // x = -3, facing +x
    Light light;
    light.intensity = 20.0f;
    add_light_node(&s, light, glm::dvec3(0.5, 1.0, 1.0));
    s.finalize();
    return s;
  };
  const Scene textured = scene_of(true, 0);
  Tracer tracer(textured);
  TraceStats stats, reference_stats;
  glm::vec3 colors[3];
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    // Texel k's center: u = (k + 0.5) / 3 on the square, x = 2 u - 1; seen from the side, so
    // that the mirror reflects the wall.
    const float x = 2.0f * (float(k) + 0.5f) / 3.0f - 1.0f;
    const Ray ray = ray_to({x + 1.5f, 0.0f, 0.0f}, {x, 0.0f, -2.0f});
    const glm::vec3 got = colors[k] = tracer.trace(ray, &stats).color;
    const Scene plain = scene_of(false, k);
    Tracer reference(plain);
    const glm::vec3 want = reference.trace(ray, &reference_stats).color;
    expect_near3(got, want, 1e-5f * std::max(1.0f, std::max(want.r, std::max(want.g, want.b))),
                 "textured against plain");
  }
  // Only the polished metal's point is a mirror (one reflection ray, to the wall), and the
  // three points differ: the textures are read, not the factors alone.
  EXPECT_EQ(stats.reflection_rays, 1u);
  EXPECT_GT(glm::length(colors[0] - colors[2]), 0.1f);
  EXPECT_GT(glm::length(colors[1] - colors[2]), 0.1f);
}

// The normal-texture tests' scene: a white Lambertian square at z = -2 whose normal texture is
// one texel (its scale `scale`), under a directional light along -(1, 0, 1) (from the right, in
// front). `dress(scene, square, node)` sets the square's coordinates, tangents and node before
// the scene is finished (the square is added first: its mesh is set when `dress` runs). Returns
// n.l at (0.2, 0.1): the color x pi / intensity.
float normal_mapped_n_dot_l(glm::vec3 texel, float scale,
                            const std::function<void(Scene*, Mesh*, int)>& dress) {
  Scene s;
  Texture normal;
  normal.width = normal.height = 1;
  normal.texels = {texel};
  s.textures.push_back(normal);
  const int mat = add_material(&s, glm::vec3(1.0f), 0.0f, 1.0f);
  s.materials[size_t(mat)].normal_texture = 0;
  s.materials[size_t(mat)].normal_scale = scale;
  const int node = add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
  dress(&s, &s.meshes[size_t(s.nodes[size_t(node)].mesh)], node);
  Light sun;
  sun.type = Light::Type::kDirectional;
  sun.intensity = 2.0f;
  // -Z turned 45 degrees about +y shines along -(1, 0, 1).
  add_light_node(&s, sun, glm::dvec3(0.0), glm::angleAxis(0.25 * M_PI, glm::dvec3(0, 1, 0)));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const ShadedSample hit = tracer.trace(Ray{{0.2f, 0.1f, 0.0f}, {0, 0, -1}}, &stats);
  EXPECT_TRUE(hit.hit);
  EXPECT_NEAR(hit.color.r, hit.color.b, 1e-6f);
  return hit.color.r * float(M_PI) / 2.0f;
}

// A normal texture bends the shading normal in the triangle's tangent frame: a texel tilting
// the normal 30 degrees toward +u (tangent-space x) lights a white Lambertian square under a
// directional light from (1, 0, 1) as a square turned that way would: n.l = cos 15 degrees
// where +u is world +x, sin 60 / sqrt 2 where +u is world +y; tilted toward tangent-space +y
// (up in the texture: glTF's v runs down), it turns toward where v decreases. Scale 0 leaves
// the square flat.
TEST(TracerTest, NormalTextureBendsTheShadingNormalInTheTangentFrame) {
  const float sin30 = 0.5f, cos30 = std::sqrt(3.0f) / 2.0f;
  // uvs of the square's corners c, c + eu, c + eu + ev, c + ev (eu = +x, ev = +y), and the
  // texel; returns n.l (color x pi / intensity: base white, diffuse only).
  auto lit = [&](std::vector<glm::vec2> uvs, glm::vec3 texel, float scale) {
    return normal_mapped_n_dot_l(
        texel, scale, [&](Scene*, Mesh* square, int) { square->primitives[0].uvs = uvs; });
  };
  // glTF's orientation: u to the right, v down the image (here: down in world y).
  const std::vector<glm::vec2> upright = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  // Turned: u up the square (world +y), v to the right (world +x).
  const std::vector<glm::vec2> turned = {{0, 0}, {0, 1}, {1, 1}, {1, 0}};
  const glm::vec3 toward_u(0.5f + 0.5f * sin30, 0.5f, 0.5f + 0.5f * cos30);
  const glm::vec3 toward_up(0.5f, 0.5f + 0.5f * sin30, 0.5f + 0.5f * cos30);
  const float flat = 1.0f / std::sqrt(2.0f);
  EXPECT_NEAR(lit(upright, {0.5f, 0.5f, 1.0f}, 1.0f), flat, 1e-4f);
  EXPECT_NEAR(lit(upright, toward_u, 1.0f), std::cos(float(M_PI) / 12.0f), 1e-4f);
  EXPECT_NEAR(lit(turned, toward_u, 1.0f), cos30 * flat, 1e-4f);
  // Up in the texture is world +y upright (no x: as flat tilted out of the light's plane), and
  // world -x turned (v decreases leftward): away from the light.
  EXPECT_NEAR(lit(upright, toward_up, 1.0f), cos30 * flat, 1e-4f);
  EXPECT_NEAR(lit(turned, toward_up, 1.0f), (cos30 - sin30) * flat, 1e-4f);
  EXPECT_NEAR(lit(upright, toward_u, 0.0f), flat, 1e-4f);
}

// A primitive's TANGENT sets the normal texture's frame instead of the triangle's own: t the
// tangent, b = n x t times its w. The square of the test above, upright (+u is world +x), with
// tangents along world +y: a texel tilting toward +u turns the normal toward +y (n.l = cos 30 /
// sqrt 2, not the cos 15 of the triangle's frame), one tilting up toward b = -x (w = +1) or +x
// (w = -1). Tangents turn with their node (turned half round z: +x becomes -x), and a mirroring
// node turns the sign of b with them.
TEST(TracerTest, TangentsSetTheNormalTexturesFrame) {
  const float sin30 = 0.5f, cos30 = std::sqrt(3.0f) / 2.0f;
  auto lit = [&](glm::vec4 tangent, glm::vec3 texel, glm::dquat rotation, glm::dvec3 scale) {
    return normal_mapped_n_dot_l(texel, 1.0f, [&](Scene* s, Mesh* square, int node) {
      square->primitives[0].uvs = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
      square->primitives[0].tangents.assign(4, tangent);
      s->nodes[size_t(node)].rotation = rotation;
      s->nodes[size_t(node)].scale = scale;
    });
  };
  const glm::vec3 toward_u(0.5f + 0.5f * sin30, 0.5f, 0.5f + 0.5f * cos30);
  const glm::vec3 toward_up(0.5f, 0.5f + 0.5f * sin30, 0.5f + 0.5f * cos30);
  const float flat = 1.0f / std::sqrt(2.0f);
  const glm::dquat none(1.0, 0.0, 0.0, 0.0);
  const glm::dquat half_turn = glm::angleAxis(M_PI, glm::dvec3(0, 0, 1));
  const glm::dvec3 one(1.0), mirror_x(-1.0, 1.0, 1.0);
  EXPECT_NEAR(lit({0, 1, 0, 1}, toward_u, none, one), cos30 * flat, 1e-4f);
  EXPECT_NEAR(lit({0, 1, 0, 1}, toward_up, none, one), (cos30 - sin30) * flat, 1e-4f);
  EXPECT_NEAR(lit({0, 1, 0, -1}, toward_up, none, one), std::cos(float(M_PI) / 12.0f), 1e-4f);
  // Half round z: the tangent +x points along world -x, away from the light.
  EXPECT_NEAR(lit({1, 0, 0, 1}, toward_u, half_turn, one), (cos30 - sin30) * flat, 1e-4f);
  // Mirrored in x: b = n x t x w is -x in the mesh, so +x in the world, toward the light.
  EXPECT_NEAR(lit({0, 1, 0, 1}, toward_up, none, mirror_x), std::cos(float(M_PI) / 12.0f), 1e-4f);
}

// A morphed square's tangents are its morph's (Scene::deform): the square of the test above,
// upright, with tangents along +x that a target at weight 1 turns to +y, lights as the +y
// tangents above do (cos 30 / sqrt 2), not as the file's +x or the triangle's frame (cos 15);
// as a fixed pose and with its weight animated (the tracer's deforming geometry).
TEST(TracerTest, DeformedTangentsSetTheNormalTexturesFrame) {
  const float sin30 = 0.5f, cos30 = std::sqrt(3.0f) / 2.0f;
  const glm::vec3 toward_u(0.5f + 0.5f * sin30, 0.5f, 0.5f + 0.5f * cos30);
  auto lit = [&](float weight, bool animated) {
    return normal_mapped_n_dot_l(toward_u, 1.0f, [&](Scene* s, Mesh* square, int node) {
      Primitive& p = square->primitives[0];
      p.uvs = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
      p.tangents.assign(4, glm::vec4(1, 0, 0, 1));
      MorphTarget turn;
      turn.positions.assign(4, glm::vec3(0.0f));
      turn.tangents.assign(4, glm::vec3(-1, 1, 0));
      p.targets = {turn};
      square->weights = {weight};
      if (animated) {
        AnimationChannel c;
        c.node = node;
        c.path = AnimatedPath::kWeights;
        c.times = {0.0, 10.0};
        c.weights = {weight, weight};
        c.weight_count = 1;
        s->channels.push_back(c);
      }
    });
  };
  for (bool animated : {false, true}) {
    SCOPED_TRACE(animated ? "animated" : "a fixed pose");
    EXPECT_NEAR(lit(1.0f, animated), cos30 / std::sqrt(2.0f), 1e-4f);
    EXPECT_NEAR(lit(0.0f, animated), std::cos(float(M_PI) / 12.0f), 1e-4f);
  }
}

// Each texture reads the coordinate set its slot names (Material::TextureSets): a square under
// ambient light whose base color (red | green) reads set 0, u running right, and whose occlusion
// (0.25 | 1) reads set 1, u running left, shows red at full light on its left and green at a
// quarter on its right. Where the primitive lacks set 1, the occlusion's factor alone decides
// (no occlusion) and the base color is still read. The normal texture's frame comes from its own
// set: with set 0 degenerate and set 1 upright, a texel tilting toward +u bends the normal as in
// the test above.
TEST(TracerTest, EachTextureReadsItsOwnCoordinateSet) {
  auto colors_at = [](bool with_set_1) {
    Scene s;
    s.ambient = glm::vec3(1.0f);
    Texture base, occlusion;
    base.width = occlusion.width = 2;
    base.height = occlusion.height = 1;
    base.texels = {{1, 0, 0}, {0, 1, 0}};
    occlusion.texels = {{0.25f, 0, 0}, {1, 0, 0}};  // red is the occlusion
    s.textures = {base, occlusion};
    const int mat = add_material(&s, glm::vec3(0.5f, 0.8f, 0.6f), 0.0f, 1.0f);
    Material& m = s.materials[size_t(mat)];
    m.base_color_texture = 0;
    m.occlusion_texture = 1;
    m.uv_set.occlusion = 1;
    Mesh square = quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat);
    if (with_set_1) square.primitives[0].more_uvs = {{{1, 0}, {0, 0}, {0, 1}, {1, 1}}};
    add_mesh_node(&s, square);
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    // Texel centers: x = -0.5 is u = 0.25 in set 0 and 0.75 in set 1.
    return std::array<glm::vec3, 2>{
        tracer.trace(Ray{{-0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats).color,
        tracer.trace(Ray{{0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats).color};
  };
  const std::array<glm::vec3, 2> both = colors_at(true);
  expect_near3(both[0], {0.5f, 0.0f, 0.0f}, 1e-5f, "left: red, unoccluded");
  expect_near3(both[1], {0.0f, 0.8f * 0.25f, 0.0f}, 1e-5f, "right: green, occluded to 0.25");
  const std::array<glm::vec3, 2> set_0_only = colors_at(false);
  expect_near3(set_0_only[0], {0.5f, 0.0f, 0.0f}, 1e-5f, "left, without set 1");
  expect_near3(set_0_only[1], {0.0f, 0.8f, 0.0f}, 1e-5f, "right, without set 1");

  const float sin30 = 0.5f, cos30 = std::sqrt(3.0f) / 2.0f;
  const glm::vec3 toward_u(0.5f + 0.5f * sin30, 0.5f, 0.5f + 0.5f * cos30);
  auto lit = [&](int normal_set) {
    return normal_mapped_n_dot_l(toward_u, 1.0f, [&](Scene* s, Mesh* square, int) {
      Primitive& p = square->primitives[0];
      p.uvs.assign(4, glm::vec2(0.5f));  // no frame: the normal stays
      p.more_uvs = {{{0, 1}, {1, 1}, {1, 0}, {0, 0}}};
      s->materials[size_t(p.material)].uv_set.normal = uint8_t(normal_set);
    });
  };
  EXPECT_NEAR(lit(1), std::cos(float(M_PI) / 12.0f), 1e-4f);
  EXPECT_NEAR(lit(0), 1.0f / std::sqrt(2.0f), 1e-4f);
}

// KHR_materials_unlit: the base color (factor x texture x vertex color) as it is, whatever
// the lights, the ambient light, the emission and a polished metal's reflection would add.
TEST(TracerTest, UnlitMaterialShowsItsBaseColorAsItIs) {
  Scene s;
  s.ambient = glm::vec3(0.5f);
  s.background = glm::vec3(0.0f, 0.0f, 1.0f);
  Texture tex;
  tex.width = tex.height = 1;
  tex.texels = {{0.5f, 1.0f, 1.0f}};
  s.textures.push_back(tex);
  const int mat = add_material(&s, glm::vec3(0.2f, 0.4f, 0.6f), 1.0f, 0.0f);
  Material& m = s.materials[size_t(mat)];
  m.unlit = true;
  m.emissive = glm::vec3(3.0f);
  m.base_color_texture = 0;
  Mesh square = quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat);
  square.primitives[0].colors.assign(4, glm::vec3(1.0f, 1.0f, 0.5f));
  add_mesh_node(&s, square);
  Light light;
  light.intensity = 50.0f;
  add_light_node(&s, light, glm::dvec3(0.0, 0.0, 1.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const ShadedSample hit = tracer.trace(Ray{{0.3f, 0.2f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(hit.color, {0.1f, 0.4f, 0.3f}, 1e-6f, "unlit");
  EXPECT_EQ(stats.reflection_rays, 0u);
  EXPECT_EQ(stats.shadow_rays, 0u);
}

// Traces crosshairs over a 16 x 16 image (every other column, every third row) as packets,
// expects each of their five samples to be what a single ray gives, and returns their centers.
std::vector<ShadedSample> crosshairs_match_single_rays(const Tracer& tracer, const Camera& cam,
                                                       TraceStats* stats) {
  constexpr int kSide = 16;
  std::vector<ShadedSample> centers;
  for (int j = 1; j < kSide - 1; j += 3) {
    for (int i = 1; i < kSide - 1; i += 2) {
      std::array<ShadedSample, 5> cross;
      tracer.trace_crosshair(cam, i + 0.5, j + 0.5, kSide, kSide, &cross, stats);
      const glm::dvec2 at[5] = {{0, 0}, {-1, 0}, {1, 0}, {0, -1}, {0, 1}};
      for (int k = 0; k < 5; ++k) {
        const Ray ray = cam.ray(i + 0.5 + at[k].x, j + 0.5 + at[k].y, kSide, kSide);
        expect_near3(cross[size_t(k)].color, tracer.trace(ray, stats).color, 1e-5f,
                     "crosshair against a single ray");
      }
      centers.push_back(cross[0]);
    }
  }
  return centers;
}

// alphaMode MASK: a red square whose texture's alpha is 0.2 on its left half and 0.9 on its
// right (cutoff 0.5) before a green wall, and beside it a square whose factor's alpha alone
// (0.3) is below the cutoff. Camera rays, single and in the crosshair's packets, and occlusion
// rays pass through where the surface is cut away and stop where it is not.
TEST(TracerTest, MaskedSurfacesAreCutAwayForEveryRay) {
  Scene s;
  s.ambient = glm::vec3(1.0f);  // ambient light only: a surface shows its base color
  Texture tex;
  tex.width = 2;
  tex.height = 1;
  tex.texels = {{1, 1, 1}, {1, 1, 1}};
  tex.alpha = {0.2f, 0.9f};
  s.textures.push_back(tex);
  const int red = add_material(&s, {1, 0, 0}, 0.0f, 1.0f);
  s.materials[size_t(red)].base_color_texture = 0;
  s.materials[size_t(red)].alpha_mode = Material::AlphaMode::kMask;
  const int faint = add_material(&s, {0, 0, 1}, 0.0f, 1.0f);
  s.materials[size_t(faint)].base_color_factor.a = 0.3f;
  s.materials[size_t(faint)].alpha_mode = Material::AlphaMode::kMask;
  const int green = add_material(&s, {0, 1, 0}, 0.0f, 1.0f);
  add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, red));
  add_mesh_node(&s, quad_mesh({1.5f, -1, -2}, {1, 0, 0}, {0, 2, 0}, faint));
  add_mesh_node(&s, quad_mesh({-4, -4, -4}, {8, 0, 0}, {0, 8, 0}, green));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  // u = 0.25 and 0.75 are the two texels' centers: x = -0.5 and 0.5.
  const ShadedSample cut = tracer.trace(Ray{{-0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats);
  const ShadedSample kept = tracer.trace(Ray{{0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats);
  const ShadedSample faint_hit = tracer.trace(Ray{{2.0f, 0.0f, 0.0f}, {0, 0, -1}}, &stats);
  expect_near3(cut.color, {0, 1, 0}, 1e-5f, "through the cut-away half");
  expect_near3(kept.color, {1, 0, 0}, 1e-5f, "the opaque half");
  expect_near3(faint_hit.color, {0, 1, 0}, 1e-5f, "through the faint square");
  EXPECT_NEAR(cut.position.z, -4.0f, 1e-4f);  // on the wall
  EXPECT_FALSE(tracer.occluded({-0.5f, 0.0f, 0.0f}, {-0.5f, 0.0f, -3.0f}, &stats));
  EXPECT_TRUE(tracer.occluded({0.5f, 0.0f, 0.0f}, {0.5f, 0.0f, -3.0f}, &stats));
  EXPECT_FALSE(tracer.occluded({2.0f, 0.0f, 0.0f}, {2.0f, 0.0f, -3.0f}, &stats));

  // The crosshair's packets see what single rays see, both halves among them.
  const Camera cam = Camera::look_at({0.0, 0.0, 0.0}, {0.0, 0.0, -1.0}, {0, 1, 0}, 1.2, 0.01);
  int saw_red = 0, saw_green = 0;
  for (const ShadedSample& center : crosshairs_match_single_rays(tracer, cam, &stats)) {
    saw_red += center.color.r > 0.5f;
    saw_green += center.color.g > 0.5f;
  }
  EXPECT_GT(saw_red, 0);
  EXPECT_GT(saw_green, 0);
}

// alphaMode BLEND: a red square of opacity 0.3 before a green wall, beside it two stacked blue
// squares of opacity 0.5 each, and a square of opacity 0. Lit by ambient light only, a camera
// ray through the red square sees 0.3 red over 0.7 green, through the blue ones 0.75 blue
// (0.5 + 0.5 x 0.5) over 0.25 green; the square of opacity 0 is not there for any ray. Under a
// light shining along -z (no ambient), the wall behind the red square gets 0.7 of the light
// that reaches it elsewhere. The crosshair's packets see what single rays see.
TEST(TracerTest, BlendedSurfacesShowInProportionToTheirOpacity) {
  auto scene = [](bool lit) {
    Scene s;
    if (!lit) s.ambient = glm::vec3(1.0f);
    const int red = add_material(&s, {1, 0, 0}, 0.0f, 1.0f);
    s.materials[size_t(red)].base_color_factor.a = 0.3f;
    s.materials[size_t(red)].alpha_mode = Material::AlphaMode::kBlend;
    const int blue = add_material(&s, {0, 0, 1}, 0.0f, 1.0f);
    s.materials[size_t(blue)].base_color_factor.a = 0.5f;
    s.materials[size_t(blue)].alpha_mode = Material::AlphaMode::kBlend;
    const int clear = add_material(&s, {1, 1, 1}, 0.0f, 1.0f);
    s.materials[size_t(clear)].base_color_factor.a = 0.0f;
    s.materials[size_t(clear)].alpha_mode = Material::AlphaMode::kBlend;
    const int green = add_material(&s, {0, 1, 0}, 0.0f, 1.0f);
    add_mesh_node(&s, quad_mesh({-2, -1, -2}, {2, 0, 0}, {0, 2, 0}, red));
    add_mesh_node(&s, quad_mesh({1, -1, -2}, {2, 0, 0}, {0, 2, 0}, blue));
    add_mesh_node(&s, quad_mesh({1, -1, -2.5f}, {2, 0, 0}, {0, 2, 0}, blue));
    add_mesh_node(&s, quad_mesh({4, -1, -2}, {2, 0, 0}, {0, 2, 0}, clear));
    add_mesh_node(&s, quad_mesh({-8, -8, -4}, {16, 0, 0}, {0, 16, 0}, green));
    if (lit) {
      Light sun;
      sun.type = Light::Type::kDirectional;
      add_light_node(&s, sun, glm::dvec3(0.0));  // its -Z: shining along -z
    }
    s.finalize();
    return s;
  };
  const Scene ambient = scene(false);
  Tracer tracer(ambient);
  TraceStats stats;
  const auto seen = [&](float x) { return tracer.trace(Ray{{x, 0.2f, 0.0f}, {0, 0, -1}}, &stats); };
  expect_near3(seen(-1.0f).color, {0.3f, 0.7f, 0.0f}, 1e-5f, "through the red square");
  expect_near3(seen(2.0f).color, {0.0f, 0.25f, 0.75f}, 1e-5f, "through both blue squares");
  expect_near3(seen(5.0f).color, {0.0f, 1.0f, 0.0f}, 1e-5f, "through the clear square");
  EXPECT_NEAR(seen(-1.0f).position.z, -2.0f, 1e-4f);  // the sample is the front surface's
  EXPECT_NEAR(seen(5.0f).position.z, -4.0f, 1e-4f);
  EXPECT_TRUE(tracer.occluded({-1.0f, 0.2f, 0.0f}, {-1.0f, 0.2f, -3.0f}, &stats));
  EXPECT_FALSE(tracer.occluded({5.0f, 0.2f, 0.0f}, {5.0f, 0.2f, -3.0f}, &stats));

  const Scene lit = scene(true);
  Tracer lit_tracer(lit);
  // From between the squares and the wall: the wall in the red square's shadow, and in none.
  const glm::vec3 shaded = lit_tracer.trace(Ray{{-1.0f, 0.2f, -3.0f}, {0, 0, -1}}, &stats).color;
  const glm::vec3 open = lit_tracer.trace(Ray{{-5.0f, 0.2f, -3.0f}, {0, 0, -1}}, &stats).color;
  ASSERT_GT(open.g, 0.0f);
  EXPECT_NEAR(shaded.g / open.g, 0.7f, 1e-4f);
  const glm::vec3 twice = lit_tracer.trace(Ray{{2.0f, 0.2f, -3.0f}, {0, 0, -1}}, &stats).color;
  EXPECT_NEAR(twice.g / open.g, 0.25f, 1e-4f);  // behind both blue squares

  const Camera cam = Camera::look_at({0.0, 0.0, 0.0}, {0.0, 0.0, -1.0}, {0, 1, 0}, 1.6, 0.01);
  int saw_blend = 0;
  for (const ShadedSample& center : crosshairs_match_single_rays(tracer, cam, &stats)) {
    saw_blend += center.color.r > 0.2f && center.color.g > 0.5f;  // 0.3 red over 0.7 green
  }
  EXPECT_GT(saw_blend, 0);
}

// Texture minification by ray cones: a floor with a one-texel checker (1024 x 1024 texels over
// 1 x 1, repeated 20 times over the 20 x 20 floor), lit by ambient light only, seen from 1 above
// at 64 x 48 pixels. Every pixel covers many texels: with the camera's ray cones the samples are
// the checker's mean, 0.5, near and far (a grazing floor blurs, it does not alias); thin rays
// (spread 0) read single texels and alias to 0 and 1. Near the camera, where a texel is larger
// than the cone, the cone reads the texture as thin rays do (no blur where none is needed).
TEST(TracerTest, RayConesFilterMinifiedTexturesAndLeaveMagnifiedOnesSharp) {
  const auto checker_floor = [](int size, float repeats) {
    Scene s;
    s.ambient = glm::vec3(1.0f);
    Texture tex;
    tex.width = tex.height = size;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) tex.texels.push_back(glm::vec3(float((x + y) % 2)));
    }
    s.textures.push_back(tex);
    const int mat = add_material(&s, glm::vec3(1.0f), 0.0f, 1.0f);
    s.materials[size_t(mat)].base_color_texture = 0;
    Mesh floor = quad_mesh({-10, 0, 10}, {20, 0, 0}, {0, 0, -20}, mat);
    for (glm::vec2& uv : floor.primitives[0].uvs) uv *= repeats;
    add_mesh_node(&s, floor);
    s.finalize();
    return s;
  };
  const Camera cam = Camera::look_at({0.0, 1.0, 5.0}, {0.0, 0.0, -5.0}, {0, 1, 0}, 0.9, 0.01);
  const int w = 64, h = 48;
  const auto spread_of = [&](const Scene& s, bool cones) {
    Tracer tracer(s);
    TraceStats stats;
    double sum = 0.0, sum2 = 0.0;
    int n = 0;
    for (int y = h / 2 + 2; y < h; ++y) {  // the floor, from far to near
      for (int x = 0; x < w; ++x) {
        Ray ray = cam.ray(x + 0.5, y + 0.5, w, h);
        if (!cones) ray.spread = 0.0f;
        const ShadedSample o = tracer.trace(ray, &stats);
        if (!o.hit) continue;
        sum += o.color.g;
        sum2 += double(o.color.g) * o.color.g;
        ++n;
      }
    }
    const double mean = sum / n;
    return std::pair{mean, std::sqrt(std::max(0.0, sum2 / n - mean * mean))};
  };
  const Scene fine = checker_floor(1024, 20.0f);
  const auto [filtered_mean, filtered_sd] = spread_of(fine, true);
  const auto [thin_mean, thin_sd] = spread_of(fine, false);
  std::printf("one-texel checker: mean %.3f sd %.3f with cones, sd %.3f with thin rays\n",
              filtered_mean, filtered_sd, thin_sd);
  EXPECT_NEAR(filtered_mean, 0.5, 0.02);
  EXPECT_LT(filtered_sd, 0.03);
  EXPECT_GT(thin_sd, 0.1);  // bilinear at random points of a one-texel checker: 1/6
  // A coarse checker (2 x 2 texels over the floor's unit square: each texel half a unit, many
  // pixels wide here): the cones change nothing.
  const Scene coarse = checker_floor(2, 1.0f);
  Tracer a(coarse);
  TraceStats stats;
  for (int x = 4; x < w; x += 8) {
    Ray ray = cam.ray(x + 0.5, h - 2.5, w, h);
    const ShadedSample cone = a.trace(ray, &stats);
    ray.spread = 0.0f;
    expect_near3(cone.color, a.trace(ray, &stats).color, 1e-6f, "magnified texel");
  }
}

// A mirror square in z = -3 facing +Z and an emissive red wall in z = +1 facing it.
Scene mirror_scene(glm::vec3 mirror_base) {
  Scene s;
  s.background = glm::vec3(0.0f, 0.0f, 0.3f);
  const int mirror = add_material(&s, mirror_base, 1.0f, 0.0f);
  const int wall = add_material(&s, glm::vec3(0.0f), 0.0f, 1.0f);
  s.materials[size_t(wall)].emissive = glm::vec3(1.0f, 0.0f, 0.0f);
  add_mesh_node(&s, quad_mesh({-5, -5, -3}, {10, 0, 0}, {0, 10, 0}, mirror));
  add_mesh_node(&s, quad_mesh({-5, -5, 1}, {0, 10, 0}, {10, 0, 0}, wall));
  s.finalize();
  return s;
}

TEST(TracerTest, MirrorReflectsWhatItFaces) {
  const Ray straight{{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, -1.0f}};
  const Ray oblique{{0.0f, 0.0f, -1.0f}, glm::normalize(glm::vec3(0.4f, 0.2f, -1.0f))};
  TraceStats stats;
  {
    // A perfect mirror (F0 = 1 at every angle) shows the wall as it is.
    Tracer tracer(mirror_scene(glm::vec3(1.0f)));
    expect_near3(tracer.trace(straight, &stats).color, {1, 0, 0}, 1e-5f, "white mirror");
    expect_near3(tracer.trace(oblique, &stats).color, {1, 0, 0}, 1e-5f, "oblique");
    EXPECT_EQ(stats.reflection_rays, 2u);
  }
  {
    // At normal incidence Fresnel is F0 = the base color of a metal.
    Tracer tracer(mirror_scene(glm::vec3(0.5f, 0.7f, 0.9f)));
    expect_near3(tracer.trace(straight, &stats).color, {0.5f, 0, 0}, 1e-5f, "tinted mirror");
  }
  {
    // Looking away from the wall, the mirror shows the background.
    Tracer tracer(mirror_scene(glm::vec3(1.0f)));
    const Ray away{{0.0f, 0.0f, -1.0f}, glm::normalize(glm::vec3(2.0f, 0.0f, -1.0f))};
    expect_near3(tracer.trace(away, &stats).color, {0.0f, 0.0f, 0.3f}, 1e-5f, "background");
  }
  {
    // Without reflection depth the mirror is black (it has no diffuse part).
    TracerOptions o;
    o.max_mirror_depth = 0;
    Tracer tracer(mirror_scene(glm::vec3(1.0f)), o);
    expect_near3(tracer.trace(straight, &stats).color, {0, 0, 0}, 1e-6f, "depth 0");
  }
}

// KHR_materials_clearcoat: a clear layer over the material takes clearcoat x F_coat(n.v) of the
// light (F0 0.04), the material beneath the rest. Seen and lit straight on (n = v = l: F_coat =
// 0.04), a white Lambertian square under a full coat of roughness 0.5 shows the light x (0.96 /
// pi + 0.04 x D x vis), D = 1 / (pi alpha^2) and vis = 1/4 at alpha = 0.25; under half a coat,
// half the change. The coat lies over the emission too: straight on, 0.96 of it comes through.
// A smooth coat reflects the wall facing it: 0.04 of it over a black dielectric (nothing without
// reflection depth), and over a metal mirror of F0 0.5 the coat's 0.04 plus 0.96 of the metal's
// 0.5.
TEST(TracerTest, ClearcoatLayersAClearDielectricOverTheMaterial) {
  const auto lit = [](float clearcoat, glm::vec3 emissive = glm::vec3(0.0f)) {
    return square_lit_straight_on([&](Material* m) {
      m->clearcoat = clearcoat;
      m->clearcoat_roughness = 0.5f;
      m->emissive = emissive;
    });
  };
  const float pi = float(M_PI), alpha = 0.25f;
  const float coat = 0.04f / (pi * alpha * alpha) * 0.25f;
  expect_near3(lit(0.0f), glm::vec3(3.0f / pi), 1e-4f, "no coat");
  expect_near3(lit(1.0f), glm::vec3(3.0f * (0.96f / pi + coat)), 1e-4f, "full coat");
  expect_near3(lit(0.5f), glm::vec3(3.0f * (0.98f / pi + 0.5f * coat)), 1e-4f, "half a coat");
  expect_near3(lit(1.0f, {0.5f, 0.0f, 0.0f}) - lit(1.0f), {0.96f * 0.5f, 0.0f, 0.0f}, 1e-4f,
               "emission under the coat");

  const Ray straight{{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, -1.0f}};
  const auto reflected = [&](float metallic, glm::vec3 base, int depth) {
    Scene s = mirror_scene(base);
    s.materials[0].metallic = metallic;
    s.materials[0].roughness = metallic > 0.0f ? 0.0f : 1.0f;
    s.materials[0].clearcoat = 1.0f;
    TracerOptions o;
    o.max_mirror_depth = depth;
    Tracer tracer(s, o);
    TraceStats stats;
    return tracer.trace(straight, &stats).color;
  };
  expect_near3(reflected(0.0f, glm::vec3(0.0f), 3), {0.04f, 0, 0}, 1e-5f, "coat alone");
  expect_near3(reflected(0.0f, glm::vec3(0.0f), 0), {0, 0, 0}, 1e-6f, "depth 0");
  expect_near3(reflected(1.0f, glm::vec3(0.5f), 3), {0.04f + 0.96f * 0.5f, 0, 0}, 1e-5f,
               "over a metal");
}

// The extensions' textures multiply their factors at each point, as the core's do: a square lit
// straight on shows with factor 1 and a texel of x what it shows with factor x and no texture:
// the specular strength (the texture's red: the image's alpha), the specular color, the
// clearcoat and its roughness. Over a square whose left texel is 0 and right 1, the coat shows
// on the right only.
TEST(TracerTest, ExtensionTexturesMultiplyTheirFactors) {
  const auto textured = [](const std::function<void(Scene*, Material*)>& dress) {
    return square_lit_straight_on_scene(dress);
  };
  const auto black_dielectric = [](Material* m) {
    m->base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
    m->roughness = 0.5f;
    m->has_specular_extension = true;
  };
  expect_near3(textured([&](Scene* s, Material* m) {
                 black_dielectric(m);
                 m->specular_texture = add_texel(s, glm::vec3(0.5f));
               }),
               textured([&](Scene*, Material* m) {
                 black_dielectric(m);
                 m->specular = 0.5f;
               }),
               1e-6f, "specular strength");
  const glm::vec3 tint(1.0f, 0.5f, 0.25f);
  expect_near3(textured([&](Scene* s, Material* m) {
                 black_dielectric(m);
                 m->specular_color_texture = add_texel(s, tint);
               }),
               textured([&](Scene*, Material* m) {
                 black_dielectric(m);
                 m->specular_color = tint;
               }),
               1e-6f, "specular color");
  const glm::vec3 half_coat = textured([&](Scene*, Material* m) {
    m->clearcoat = 0.5f;
    m->clearcoat_roughness = 0.5f;
  });
  expect_near3(textured([&](Scene* s, Material* m) {
                 m->clearcoat = 1.0f;
                 m->clearcoat_roughness = 0.5f;
                 m->clearcoat_texture = add_texel(s, {0.5f, 0.0f, 0.0f});  // red
               }),
               half_coat, 1e-6f, "clearcoat");
  expect_near3(textured([&](Scene* s, Material* m) {
                 m->clearcoat = 0.5f;
                 m->clearcoat_roughness = 1.0f;
                 m->clearcoat_roughness_texture = add_texel(s, {0.0f, 0.5f, 0.0f});  // green
               }),
               half_coat, 1e-6f, "clearcoat roughness");
  ASSERT_GT(std::abs(half_coat.r - textured([](Scene*, Material*) {}).r), 1e-3f);

  // Left texel 0, right texel 1 (u runs with x across the square).
  Scene s;
  s.background = glm::vec3(0.0f);
  const int mat = add_material(&s, glm::vec3(0.0f), 0.0f, 1.0f);
  Texture halves;
  halves.width = 2;
  halves.height = 1;
  halves.texels = {glm::vec3(0.0f), glm::vec3(1.0f)};
  s.textures.push_back(halves);
  s.materials[size_t(mat)].clearcoat = 1.0f;
  s.materials[size_t(mat)].clearcoat_roughness = 0.5f;
  s.materials[size_t(mat)].clearcoat_texture = 0;
  add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
  Light sun;
  sun.type = Light::Type::kDirectional;
  sun.intensity = 3.0f;
  add_light_node(&s, sun, glm::dvec3(0.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const float pi = float(M_PI), alpha = 0.25f;
  const float coat = 3.0f * 0.04f / (pi * alpha * alpha) * 0.25f;
  expect_near3(tracer.trace(Ray{{-0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats).color, glm::vec3(0.0f),
               1e-6f, "no coat on the left");
  expect_near3(tracer.trace(Ray{{0.5f, 0.0f, 0.0f}, {0, 0, -1}}, &stats).color, glm::vec3(coat),
               1e-5f, "a full coat on the right");
}

// KHR_materials_diffuse_transmission: a Lambertian square at z = -2 facing the camera at the
// origin, under an ambient term, lit by a sun either from behind the camera or from behind the
// square (shining toward the camera). Light from behind comes through as
// diffuse_transmission x its color x (1 - metallic) / pi (not the base color), and the diffuse
// reflection keeps 1 - diffuse_transmission (also beside a mirror's metal); the ambient light
// reaches both ways. A blocker behind the square shadows what comes through (the shadow ray
// leaves from the back), the extension's textures multiply its factors, and the packets'
// shading (trace_crosshair) agrees with single rays.
TEST(TracerTest, DiffuseTransmissionLetsLightThroughFromBehind) {
  const glm::vec3 base(0.8f, 0.6f, 0.4f), ambient(0.1f), color(1.0f, 0.5f, 0.25f);
  const float intensity = 3.0f, pi = std::numbers::pi_v<float>;
  struct Lit {
    glm::vec3 single, packet;
  };
  auto shade = [&](float dt, float metallic, bool from_behind, bool blocked, bool textured = false,
                   float roughness = 1.0f) {
    Scene s;
    s.ambient = ambient;
    const int mat = add_material(&s, base, metallic, roughness);
    Material& m = s.materials[size_t(mat)];
    m.diffuse_transmission = dt;
    m.diffuse_transmission_color = color;
    if (textured) {  // factors 1 and white, the texels dt and the color
      m.diffuse_transmission = 1.0f;
      m.diffuse_transmission_color = glm::vec3(1.0f);
      m.diffuse_transmission_texture = add_texel(&s, glm::vec3(dt, 0.0f, 0.0f));
      m.diffuse_transmission_color_texture = add_texel(&s, color);
    }
    add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
    if (blocked) {
      const int dark = add_material(&s, glm::vec3(0.0f), 0.0f, 1.0f);
      add_mesh_node(&s, quad_mesh({-1, -1, -3}, {2, 0, 0}, {0, 2, 0}, dark));
    }
    Light sun;
    sun.type = Light::Type::kDirectional;  // along -Z, or turned to +Z
    sun.intensity = intensity;
    add_light_node(&s, sun, glm::dvec3(0.0),
                   from_behind ? glm::angleAxis(M_PI, glm::dvec3(0.0, 1.0, 0.0))
                               : glm::dquat(1.0, 0.0, 0.0, 0.0));
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    const Camera cam =
        Camera::look_at({0.0, 0.0, 0.0}, {0.0, 0.0, -2.0}, {0.0, 1.0, 0.0}, 0.9, 0.01);
    std::array<ShadedSample, 5> cross;
    tracer.trace_crosshair(cam, 8.0, 8.0, 16, 16, &cross, &stats);
    const ShadedSample single = tracer.trace(cam.ray(8.0, 8.0, 16, 16), &stats);
    EXPECT_TRUE(single.hit);
    return Lit{single.color, cross[0].color};
  };
  auto expect = [](const Lit& got, glm::vec3 want, const char* what) {
    expect_near3(got.single, want, 1e-5f, what);
    expect_near3(got.packet, want, 1e-5f, what);
  };
  const float dt = 0.75f;
  const glm::vec3 ambient_seen = ambient * (base * (1.0f - dt) + dt * color);
  // Without the extension the square is dark from behind: ambient only.
  expect(shade(0.0f, 0.0f, true, false), ambient * base, "opaque, lit from behind");
  expect(shade(dt, 0.0f, true, false), ambient_seen + dt * color * intensity / pi,
         "transmits, lit from behind");
  expect(shade(dt, 0.0f, false, false), ambient_seen + (1.0f - dt) * base * intensity / pi,
         "transmits, lit from the front");
  expect(shade(dt, 0.0f, true, true), ambient_seen, "transmits, shadowed behind");
  expect(shade(dt, 0.0f, true, false, true), ambient_seen + dt * color * intensity / pi,
         "textured, lit from behind");
  expect(shade(dt, 0.0f, false, false, true), ambient_seen + (1.0f - dt) * base * intensity / pi,
         "textured, lit from the front");
  // A half-metallic surface transmits from its dielectric half only; its metal keeps reflecting
  // the ambient light.
  const float metallic = 0.5f;
  const float share = dt * (1.0f - metallic);
  expect(shade(dt, metallic, true, false),
         ambient * (base * (1.0f - share) + share * color) + share * color * intensity / pi,
         "half metal, lit from behind");
  // A polished one is a mirror: its metal reflects only through its reflection ray (here into
  // the black background), and its dielectric half splits as a rough one's does.
  expect(shade(dt, metallic, true, false, false, 0.0f),
         ambient * ((1.0f - metallic) * (1.0f - dt) * base + share * color) +
             share * color * intensity / pi,
         "half-metal mirror, lit from behind");
}

// KHR_materials_pbrSpecularGlossiness, on a square lit and seen straight on (Fresnel = F0):
// the specular color is F0 itself (a black diffuse shows F0 / 0.04 x glTF's core highlight of
// the same roughness), the diffuse keeps 1 - max(F0) of its light, the glossiness texel
// multiplies 1 - roughness, and glossiness 0 with white specular is a white rough metal
// (not the Lambertian surface a rough dielectric is).
TEST(TracerTest, SpecularGlossinessSetsF0AndRoughness) {
  const auto spec_gloss = [](glm::vec3 diffuse, glm::vec3 specular, float roughness) {
    return [=](Material* m) {
      m->base_color_factor = glm::vec4(diffuse, 1.0f);
      m->metallic = 0.0f;
      m->roughness = roughness;
      m->has_specular_extension = true;
      m->specular_glossiness = true;
      m->specular_color = specular;
    };
  };
  const glm::vec3 core = square_lit_straight_on([](Material* m) {
    m->base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
    m->roughness = 0.5f;
  });
  ASSERT_GT(core.r, 0.0f);
  const glm::vec3 f0(0.5f, 0.25f, 1.0f);
  expect_near3(square_lit_straight_on(spec_gloss(glm::vec3(0.0f), f0, 0.5f)), f0 * core.r / 0.04f,
               1e-5f, "F0");
  const glm::vec3 lambert = square_lit_straight_on([](Material*) {});
  const glm::vec3 f0_dim(0.5f, 0.25f, 0.0f);
  expect_near3(square_lit_straight_on(spec_gloss(glm::vec3(1.0f), f0_dim, 0.5f)),
               0.5f * lambert + f0_dim * core.r / 0.04f, 1e-5f, "diffuse less max(F0)");
  expect_near3(square_lit_straight_on_scene([&](Scene* s, Material* m) {
                 spec_gloss(glm::vec3(0.0f), f0, 0.0f)(m);
                 m->glossiness_texture = add_texel(s, {0.5f, 0.0f, 0.0f});  // red: the alpha
               }),
               square_lit_straight_on(spec_gloss(glm::vec3(0.0f), f0, 0.5f)), 1e-6f,
               "glossiness texture");
  const glm::vec3 rough_metal = square_lit_straight_on([](Material* m) {
    m->metallic = 1.0f;
    m->roughness = 1.0f;
  });
  ASSERT_GT(std::abs(rough_metal.r - lambert.r), 1e-3f);
  expect_near3(square_lit_straight_on(spec_gloss(glm::vec3(1.0f), glm::vec3(1.0f), 1.0f)),
               rough_metal, 1e-6f, "glossiness 0");
  // In ambient light too a gold of either workflow is the same gold: a metallic-roughness
  // surface reflects ambient light by its base color, a specular-glossiness one by its diffuse
  // (here black) and its F0.
  const glm::vec3 gold(1.0f, 0.8f, 0.3f);
  const auto in_ambient = [](const std::function<void(Material*)>& dress) {
    return square_lit_straight_on_scene([&](Scene* s, Material* m) {
      s->ambient = glm::vec3(0.5f);
      dress(m);
    });
  };
  const glm::vec3 metal = in_ambient([&](Material* m) {
    m->base_color_factor = glm::vec4(gold, 1.0f);
    m->metallic = 1.0f;
    m->roughness = 0.5f;
  });
  ASSERT_GT(metal.r - square_lit_straight_on([&](Material* m) {
                        m->base_color_factor = glm::vec4(gold, 1.0f);
                        m->metallic = 1.0f;
                        m->roughness = 0.5f;
                      }).r,
            0.4f);
  expect_near3(in_ambient(spec_gloss(glm::vec3(0.0f), gold, 0.5f)), metal, 1e-5f, "gold");
}

// KHR_materials_iridescence on a black dielectric square lit and seen straight on (v = l = n =
// h): the highlight's Fresnel term becomes mix(F0, F_film, weight). A film far thicker than
// light's coherence (20 um) shows no interference: F_film is the sum of the film's incoherent
// reflections, r12 + (1 - r12)^2 r23 / (1 - r12 r23) with r12 between air and the film (ior
// 1.3) and r23 between the film and the base (ior 1.5, from F0 0.04), the same in every
// channel. A film 300 nm thick colors the highlight (its channels differ); the textures scale
// the weight (red) and place the thickness between minimum and maximum (green) as the factors
// do; weight 0 is no film.
TEST(TracerTest, IridescenceMixesTheThinFilmsReflectanceIntoTheHighlight) {
  const auto highlight = [](float weight, float thickness_max,
                            const std::function<void(Scene*, Material*)>& more = {}) {
    return square_lit_straight_on_scene([&](Scene* s, Material* m) {
      m->base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
      m->roughness = 0.5f;
      m->iridescence = weight;
      m->iridescence_ior = 1.3f;
      m->iridescence_thickness_max = thickness_max;
      if (more) more(s, m);
    });
  };
  const glm::vec3 core = highlight(0.0f, 400.0f);
  ASSERT_GT(core.r, 0.0f);
  const auto f0 = [](double a, double b) { return ((a - b) / (a + b)) * ((a - b) / (a + b)); };
  const double r12 = f0(1.3, 1.0), r23 = f0(1.5, 1.3);
  const double incoherent = r12 + (1.0 - r12) * (1.0 - r12) * r23 / (1.0 - r12 * r23);
  expect_near3(highlight(1.0f, 20000.0f) / core.r, glm::vec3(float(incoherent / 0.04)), 1e-3f,
               "thick film");
  expect_near3(highlight(0.5f, 20000.0f) / core.r, glm::vec3(float(0.5 + 0.5 * incoherent / 0.04)),
               1e-3f, "half weight");
  const glm::vec3 film = highlight(1.0f, 300.0f) / core.r;
  EXPECT_GT(std::max({film.r, film.g, film.b}) - std::min({film.r, film.g, film.b}), 0.1f)
      << film.r << " " << film.g << " " << film.b;
  expect_near3(highlight(1.0f, 300.0f,
                         [](Scene* s, Material* m) {
                           m->iridescence_thickness_min = 200.0f;
                           m->iridescence_thickness_max = 400.0f;
                           m->iridescence_thickness_texture = add_texel(s, {0.0f, 0.5f, 0.0f});
                         }),
               highlight(1.0f, 300.0f), 1e-6f, "thickness texture");
  expect_near3(highlight(1.0f, 300.0f,
                         [](Scene* s, Material* m) {
                           m->iridescence_texture = add_texel(s, {0.5f, 0.0f, 0.0f});
                         }),
               highlight(0.5f, 300.0f), 1e-6f, "weight texture");
  expect_near3(highlight(0.0f, 300.0f), core, 0.0f, "no film");
}

// The film colors glass's Fresnel term too: a thin wall of glass (one square, ior 1.5) seen
// straight on, with an unlit white square behind the camera and nothing beyond the glass,
// shows exactly its reflection weight: F0 = 0.04 without a film, the film's incoherent
// reflectance under a 20 um film (as in IridescenceMixesTheThinFilmsReflectanceIntoTheHighlight),
// and their mix by the film's weight.
TEST(TracerTest, IridescenceColorsGlassReflection) {
  const auto reflected = [](float weight) {
    Scene s;
    s.background = glm::vec3(0.0f);
    const int glass = add_material(&s, glm::vec3(1.0f), 0.0f, 0.0f);
    Material& g = s.materials[size_t(glass)];
    g.transmission = 1.0f;
    g.ior = 1.5f;
    g.iridescence = weight;
    g.iridescence_ior = 1.3f;
    g.iridescence_thickness_max = 20000.0f;
    add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, glass));
    const int white = add_material(&s, glm::vec3(1.0f), 0.0f, 1.0f);
    s.materials[size_t(white)].unlit = true;
    add_mesh_node(&s, quad_mesh({-5, -5, 1}, {0, 10, 0}, {10, 0, 0}, white));  // faces -z
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    return tracer.trace(Ray{{0.1f, 0.2f, 0.0f}, {0, 0, -1}}, &stats).color;
  };
  const auto f0 = [](double a, double b) { return ((a - b) / (a + b)) * ((a - b) / (a + b)); };
  const double r12 = f0(1.3, 1.0), r23 = f0(1.5, 1.3);
  const float film = float(r12 + (1.0 - r12) * (1.0 - r12) * r23 / (1.0 - r12 * r23));
  expect_near3(reflected(0.0f), glm::vec3(0.04f), 1e-5f, "no film");
  expect_near3(reflected(1.0f), glm::vec3(film), 1e-4f, "film");
  expect_near3(reflected(0.5f), glm::vec3(0.5f * (0.04f + film)), 1e-4f, "half");
}

// The clear coat lies on its own normal (glTF's clearcoatNormal): the interpolated normal, which
// the material's normal texture does not bend, bent only by clearcoatNormalTexture. A square
// with only a coat (black base, no specular of its own) of roughness 0.5, lit and seen straight
// on, shows 3 x 0.04 x D x vis whatever its normal texture; with a coat normal tilted 30 degrees,
// the coat's lobe at n.h = n.v = n.l = cos 30 and its Fresnel there.
TEST(TracerTest, ClearcoatLiesOnItsOwnNormal) {
  const float sin30 = 0.5f, cos30 = std::sqrt(3.0f) / 2.0f;
  const glm::vec3 toward_u(0.5f + 0.5f * sin30, 0.5f, 0.5f + 0.5f * cos30);
  const auto coat_only = [&](bool base_normal, bool coat_normal) {
    return square_lit_straight_on_scene([&](Scene* s, Material* m) {
      m->base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
      m->has_specular_extension = true;
      m->specular = 0.0f;
      m->clearcoat = 1.0f;
      m->clearcoat_roughness = 0.5f;
      if (base_normal) m->normal_texture = add_texel(s, toward_u);
      if (coat_normal) m->clearcoat_normal_texture = add_texel(s, toward_u);
    });
  };
  const double pi = M_PI, a2 = 0.25 * 0.25;  // alpha = roughness^2
  // GGX D x height-correlated Smith visibility at n.h = n.v = n.l = c, times n.l, and the
  // coat's Schlick Fresnel at n.v = c.
  const auto lobe = [&](double c) {
    const double dd = c * c * (a2 - 1.0) + 1.0;
    const double d = a2 / (pi * dd * dd);
    const double vis = 0.5 / (2.0 * c * std::sqrt(c * c * (1.0 - a2) + a2));
    const double fresnel = 0.04 + 0.96 * std::pow(1.0 - c, 5.0);
    return float(3.0 * fresnel * d * vis * c);
  };
  expect_near3(coat_only(false, false), glm::vec3(lobe(1.0)), 1e-4f, "flat");
  expect_near3(coat_only(true, false), glm::vec3(lobe(1.0)), 1e-4f, "the base's normal texture");
  expect_near3(coat_only(false, true), glm::vec3(lobe(cos30)), 1e-4f, "the coat's normal texture");
  ASSERT_GT(std::abs(lobe(1.0) - lobe(cos30)), 1e-2f);
}

// KHR_materials_sheen's lobe as the extension defines it (a reference for the tests below):
// Charlie D at n.h and the visibility from its fitted lambda, for sheen roughness r.
double reference_sheen(double r, double n_dot_h, double n_dot_v, double n_dot_l) {
  const double a = r * r;
  const double d = (2.0 + 1.0 / a) * std::pow(1.0 - n_dot_h * n_dot_h, 0.5 / a) / (2.0 * M_PI);
  const double t = (1.0 - a) * (1.0 - a);
  const auto fit = [&](double x) {
    const auto mix = [t](double at1, double at0) { return at1 + (at0 - at1) * t; };
    return mix(21.5473, 25.3245) /
               (1.0 + mix(3.82987, 3.32435) * std::pow(x, mix(0.19823, 0.16801))) +
           mix(-1.97760, -1.27393) * x + mix(-4.32054, -4.85967);
  };
  const auto lambda = [&](double c) {
    return c < 0.5 ? std::exp(fit(c)) : std::exp(2.0 * fit(0.5) - fit(1.0 - c));
  };
  const double vis = std::clamp(
      1.0 / ((1.0 + lambda(n_dot_v) + lambda(n_dot_l)) * (4.0 * n_dot_v * n_dot_l)), 0.0, 1.0);
  return d * vis;
}

// The directional albedo of a white sheen of roughness r at n.v: the reference lobe x n.l over
// the hemisphere, by a midpoint rule finer than the tracer's table.
double reference_sheen_albedo(double r, double n_dot_v) {
  constexpr int kSteps = 400;
  const glm::dvec3 v(std::sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v);
  double sum = 0.0;
  for (int p = 0; p < kSteps; ++p) {
    const double nl = (p + 0.5) / kSteps, sl = std::sqrt(1.0 - nl * nl);
    for (int q = 0; q < kSteps; ++q) {
      const double phi = M_PI * (q + 0.5) / kSteps;
      const glm::dvec3 h =
          glm::normalize(v + glm::dvec3(sl * std::cos(phi), sl * std::sin(phi), nl));
      sum += reference_sheen(r, h.z, n_dot_v, nl) * nl;
    }
  }
  return sum / kSteps * (2.0 * M_PI / kSteps);
}

// KHR_materials_sheen: a black square with a white sheen of roughness 0.5, seen at theta_v from
// its normal and lit by a point light (irradiance 1) from theta_l, 90 degrees around from the
// viewer, shows the reference lobe x n.l. Under uniform ambient light of 1 alone it shows its
// directional albedo E(n.v) (the tracer's table against the reference integral), and a white
// Lambertian square under the same sheen shows exactly 1: the sheen takes from the material
// beneath what it reflects. Seen and lit straight on (where the lobe is 0), the white square
// keeps 1 - E(1) of its light; the textures multiply the color and roughness factors.
TEST(TracerTest, SheenReflectsTowardGrazingAndTakesItsAlbedoFromBeneath) {
  const float roughness = 0.5f;
  const auto sheen_scene = [&](Scene* s, glm::vec3 base) {
    const int mat = add_material(s, base, 0.0f, 1.0f);
    Material& m = s->materials[size_t(mat)];
    m.has_specular_extension = true;
    m.specular = 0.0f;  // no highlight of the base's own
    m.sheen_color = glm::vec3(1.0f);
    m.sheen_roughness = roughness;
    add_mesh_node(s, quad_mesh({-50, -50, -2}, {100, 0, 0}, {0, 100, 0}, mat));
  };
  // The color seen from the origin at theta_v (toward the viewer: (sin, 0, cos)).
  const auto seen_at = [](const Scene& s, double theta_v) {
    Tracer tracer(s);
    TraceStats stats;
    const Ray ray{{0.0f, 0.0f, 0.0f},
                  glm::vec3(-float(std::sin(theta_v)), 0.0f, -float(std::cos(theta_v)))};
    const ShadedSample out = tracer.trace(ray, &stats);
    EXPECT_TRUE(out.hit);
    return out.color;
  };
  for (const double degrees : {30.0, 60.0, 75.0}) {
    SCOPED_TRACE(degrees);
    const double theta_v = degrees * M_PI / 180.0, theta_l = 70.0 * M_PI / 180.0;
    Scene s;
    sheen_scene(&s, glm::vec3(0.0f));
    const glm::dvec3 hit(-2.0 * std::tan(theta_v), 0.0, -2.0);
    const glm::dvec3 to_light(0.0, std::sin(theta_l), std::cos(theta_l));
    Light bulb;
    bulb.intensity = 100.0f;  // at distance 10: irradiance 1
    add_light_node(&s, bulb, hit + 10.0 * to_light);
    s.finalize();
    const glm::dvec3 v(std::sin(theta_v), 0.0, std::cos(theta_v));
    const double n_dot_h = glm::normalize(v + to_light).z;
    const double lobe = reference_sheen(roughness, n_dot_h, v.z, to_light.z) * to_light.z;
    ASSERT_GT(lobe, 1e-3);
    expect_near3(seen_at(s, theta_v), glm::vec3(float(lobe)), 2e-4f * float(1.0 + lobe), "lobe");

    Scene ambient;
    ambient.ambient = glm::vec3(1.0f);
    sheen_scene(&ambient, glm::vec3(0.0f));
    ambient.finalize();
    const double albedo = reference_sheen_albedo(roughness, v.z);
    std::printf("sheen albedo at %.0f degrees: %.4f\n", degrees, albedo);
    expect_near3(seen_at(ambient, theta_v), glm::vec3(float(albedo)), 5e-3f, "albedo");
    Scene white;
    white.ambient = glm::vec3(1.0f);
    sheen_scene(&white, glm::vec3(1.0f));
    white.finalize();
    expect_near3(seen_at(white, theta_v), glm::vec3(1.0f), 1e-5f, "energy");
  }

  const auto straight_on = [&](const std::function<void(Scene*, Material*)>& sheen) {
    return square_lit_straight_on_scene([&](Scene* s, Material* m) {
      m->has_specular_extension = true;
      m->specular = 0.0f;
      sheen(s, m);
    });
  };
  const glm::vec3 full = straight_on([&](Scene*, Material* m) {
    m->sheen_color = glm::vec3(1.0f);
    m->sheen_roughness = roughness;
  });
  const float unsheened = 3.0f / float(M_PI);
  expect_near3(full, glm::vec3(unsheened * float(1.0 - reference_sheen_albedo(roughness, 1.0))),
               5e-3f, "beneath the sheen, straight on");
  const glm::vec3 half = straight_on([&](Scene*, Material* m) {
    m->sheen_color = glm::vec3(0.5f, 0.25f, 0.0f);  // its largest channel decides
    m->sheen_roughness = roughness;
  });
  ASSERT_GT(half.r - full.r, 1e-2f);
  expect_near3(straight_on([&](Scene* s, Material* m) {
                 m->sheen_color = glm::vec3(1.0f);
                 m->sheen_roughness = roughness;
                 m->sheen_color_texture = add_texel(s, {0.5f, 0.25f, 0.0f});
               }),
               half, 1e-6f, "color texture");
  const glm::vec3 smoother = straight_on([&](Scene*, Material* m) {
    m->sheen_color = glm::vec3(1.0f);
    m->sheen_roughness = 0.25f;
  });
  ASSERT_GT(std::abs(smoother.r - full.r), 1e-3f);
  expect_near3(straight_on([&](Scene* s, Material* m) {
                 m->sheen_color = glm::vec3(1.0f);
                 m->sheen_roughness = roughness;
                 m->sheen_roughness_texture = add_texel(s, glm::vec3(0.5f));  // red: the alpha
               }),
               smoother, 1e-6f, "roughness texture");
}

// KHR_materials_anisotropy: a black dielectric square (F0 0.04) of roughness 0.3, its texture
// coordinates' u along world +x (so its tangent is +x, its bitangent -y), seen straight on and
// lit by a point light (irradiance 1) tilted 40 degrees along +x, shows F x D x V x n.l of the
// extension's anisotropic GGX: alpha_t = mix(alpha, 1, strength^2) along the anisotropy's
// direction and alpha across it. Strength 0 is the isotropic lobe; along +x (rotation 0) the
// stretched lobe reaches the light, turned 90 degrees (toward the bitangent) it does not; a
// texture's red and green turn it as the rotation does, and its blue scales the strength.
TEST(TracerTest, AnisotropyStretchesTheHighlightAlongItsDirection) {
  const float roughness = 0.3f;
  const double theta = 40.0 * M_PI / 180.0;
  const glm::dvec3 to_light(std::sin(theta), 0.0, std::cos(theta)), v(0.0, 0.0, 1.0);
  const auto seen = [&](const std::function<void(Scene*, Material*)>& dress) {
    Scene s;
    const int mat = add_material(&s, glm::vec3(0.0f), 0.0f, roughness);
    Material m = s.materials[size_t(mat)];
    dress(&s, &m);
    s.materials[size_t(mat)] = m;
    add_mesh_node(&s, quad_mesh({-50, -50, -2}, {100, 0, 0}, {0, 100, 0}, mat));
    Light bulb;
    bulb.intensity = 100.0f;  // at distance 10: irradiance 1
    add_light_node(&s, bulb, glm::dvec3(0.0, 0.0, -2.0) + 10.0 * to_light);
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    return tracer.trace(Ray{{0.0f, 0.0f, 0.0f}, {0, 0, -1}}, &stats).color;
  };
  // The extension's lobe with its direction t (world), F0 0.04.
  const auto reference = [&](double strength, glm::dvec3 t) {
    const glm::dvec3 n(0.0, 0.0, 1.0), b = glm::cross(n, t), l = to_light;
    const glm::dvec3 h = glm::normalize(v + l);
    const double a = double(roughness) * roughness;
    const double at = a + (1.0 - a) * strength * strength, ab = a;
    const double th = glm::dot(t, h) / at, bh = glm::dot(b, h) / ab, nh = glm::dot(n, h);
    const double s2 = th * th + bh * bh + nh * nh;
    const double d = 1.0 / (M_PI * at * ab * s2 * s2);
    const auto len = [&](glm::dvec3 w) {
      return std::sqrt(std::pow(at * glm::dot(t, w), 2) + std::pow(ab * glm::dot(b, w), 2) +
                       std::pow(glm::dot(n, w), 2));
    };
    const double vis = 0.5 / (l.z * len(v) + v.z * len(l));
    const double fresnel = 0.04 + 0.96 * std::pow(1.0 - glm::dot(v, h), 5.0);
    return glm::vec3(float(fresnel * d * vis * l.z));
  };
  const glm::dvec3 along_x(1.0, 0.0, 0.0), along_y(0.0, -1.0, 0.0);
  const glm::vec3 isotropic = seen([](Scene*, Material*) {});
  expect_near3(isotropic, reference(0.0, along_x), 1e-5f, "isotropic");
  const auto anisotropic = [&](float rotation) {
    return seen([&](Scene*, Material* m) {
      m->anisotropy = 0.6f;
      m->anisotropy_rotation = rotation;
    });
  };
  const glm::vec3 stretched = anisotropic(0.0f), across = anisotropic(float(M_PI) / 2.0f);
  expect_near3(stretched, reference(0.6, along_x), 1e-5f * (1.0f + stretched.r), "along +x");
  expect_near3(across, reference(0.6, along_y), 1e-5f, "turned toward the bitangent");
  EXPECT_GT(stretched.r, 2.0f * isotropic.r);
  EXPECT_LT(across.r, isotropic.r);
  // Red and green (0.5, 1): direction (0, 1), the bitangent; blue 0.5 halves the strength.
  expect_near3(seen([&](Scene* s, Material* m) {
                 m->anisotropy = 0.6f;
                 m->anisotropy_texture = add_texel(s, {0.5f, 1.0f, 1.0f});
               }),
               across, 1e-5f, "texture direction");
  expect_near3(seen([&](Scene* s, Material* m) {
                 m->anisotropy = 0.6f;
                 m->anisotropy_texture = add_texel(s, {1.0f, 0.5f, 0.5f});
               }),
               reference(0.3, along_x), 1e-5f, "texture strength");
}

TEST(TracerTest, MirrorDepthIsBounded) {
  // Two facing mirrors: a ray between them bounces exactly max_mirror_depth times.
  Scene s;
  const int mirror = add_material(&s, glm::vec3(1.0f), 1.0f, 0.0f);
  add_mesh_node(&s, quad_mesh({-5, -5, -3}, {10, 0, 0}, {0, 10, 0}, mirror));
  add_mesh_node(&s, quad_mesh({-5, -5, 1}, {0, 10, 0}, {10, 0, 0}, mirror));
  s.finalize();
  for (int depth : {1, 3, 5}) {
    TracerOptions o;
    o.max_mirror_depth = depth;
    Tracer tracer(s, o);
    TraceStats stats;
    tracer.trace(Ray{{0, 0, 0}, {0, 0, -1}}, &stats);
    EXPECT_EQ(stats.reflection_rays, uint64_t(depth));
  }
  // A scene's own depth (the file's extras.afr_ray_depth) replaces the options'.
  for (int depth : {0, 2, 7}) {
    Scene deep = s;
    deep.ray_depth = depth;
    TracerOptions o;
    o.max_mirror_depth = 4;
    Tracer tracer(deep, o);
    EXPECT_EQ(tracer.options().max_mirror_depth, depth);
    TraceStats stats;
    tracer.trace(Ray{{0, 0, 0}, {0, 0, -1}}, &stats);
    EXPECT_EQ(stats.reflection_rays, uint64_t(depth));
  }
}

}  // namespace
}  // namespace afr::tracer_test
