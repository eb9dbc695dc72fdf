// Tests of the tracer on small scenes built here, each checked against an independent
// reference: analytic ray-plane distances, the Lambert law written out by hand, rigid-body
// velocities from the animation's own parameters, texel values, and single rays.
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

namespace afr {
namespace {

// ---------------------------------------------------------------------------------------------
// Scene building

// A quad with corners c, c + eu, c + eu + ev, c + ev, front face toward cross(eu, ev), uvs
// (0,0), (1,0), (1,1), (0,1) at those corners.
Primitive quad(glm::vec3 c, glm::vec3 eu, glm::vec3 ev, int material) {
  Primitive p;
  p.positions = {c, c + eu, c + eu + ev, c + ev};
  const glm::vec3 n = glm::normalize(glm::cross(eu, ev));
  p.normals = {n, n, n, n};
  p.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  p.indices = {0, 1, 2, 0, 2, 3};
  p.material = material;
  return p;
}

// An axis-aligned box centered at the origin with outward faces.
Mesh box_mesh(glm::vec3 half, int material) {
  Mesh m;
  m.name = "box";
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 n(0.0f), u(0.0f), v(0.0f);
      n[axis] = sign;
      u[(axis + 1) % 3] = 2.0f * half[(axis + 1) % 3];
      v[(axis + 2) % 3] = 2.0f * half[(axis + 2) % 3];
      if (sign < 0.0f) std::swap(u, v);  // keeps cross(u, v) along n
      const glm::vec3 c = n * half - 0.5f * (u + v);
      m.primitives.push_back(quad(c, u, v, material));
    }
  }
  return m;
}

Mesh quad_mesh(glm::vec3 c, glm::vec3 eu, glm::vec3 ev, int material) {
  Mesh m;
  m.name = "quad";
  m.primitives.push_back(quad(c, eu, ev, material));
  return m;
}

int add_material(Scene* s, glm::vec3 base, float metallic, float roughness) {
  Material m;
  m.base_color_factor = glm::vec4(base, 1.0f);
  m.metallic = metallic;
  m.roughness = roughness;
  s->materials.push_back(m);
  return int(s->materials.size()) - 1;
}

int add_mesh_node(Scene* s, Mesh mesh, glm::dvec3 translation = glm::dvec3(0.0)) {
  s->meshes.push_back(std::move(mesh));
  Node n;
  n.mesh = int(s->meshes.size()) - 1;
  n.translation = translation;
  s->nodes.push_back(n);
  s->roots.push_back(int(s->nodes.size()) - 1);
  return int(s->nodes.size()) - 1;
}

// A light node; `rotation` turns the light's -Z into its direction.
int add_light_node(Scene* s, Light light, glm::dvec3 position,
                   glm::dquat rotation = glm::dquat(1.0, 0.0, 0.0, 0.0)) {
  s->lights.push_back(light);
  Node n;
  n.light = int(s->lights.size()) - 1;
  n.translation = position;
  n.rotation = rotation;
  s->nodes.push_back(n);
  s->roots.push_back(int(s->nodes.size()) - 1);
  return int(s->nodes.size()) - 1;
}

// Turns -Z into -Y (a light that shines straight down).
glm::dquat pointing_down() { return glm::angleAxis(-0.5 * M_PI, glm::dvec3(1.0, 0.0, 0.0)); }

Ray ray_to(glm::vec3 from, glm::vec3 to) { return Ray{from, glm::normalize(to - from)}; }

bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void expect_near3(const glm::vec3& a, const glm::vec3& b, float tol, const char* what) {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

// ---------------------------------------------------------------------------------------------
// Geometry

TEST(TracerTest, RayIntoBoxHitsAtKnownDistance) {
  Scene s;
  const int mat = add_material(&s, glm::vec3(0.5f), 0.0f, 1.0f);
  const int node = add_mesh_node(&s, box_mesh(glm::vec3(0.5f), mat), glm::dvec3(0.0, 0.0, -5.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;

  // Straight on: the front face is the plane z = -4.5.
  ShadedSample a = tracer.trace(Ray{{0.1f, 0.2f, 0.0f}, {0.0f, 0.0f, -1.0f}}, &stats);
  ASSERT_TRUE(a.hit);
  EXPECT_EQ(a.object_id, uint32_t(node));
  expect_near3(a.position, {0.1f, 0.2f, -4.5f}, 1e-5f, "straight");
  EXPECT_EQ(a.velocity, glm::vec3(0.0f));

  // Oblique: the ray meets z = -4.5 at o + (4.5 / |d_z|) d.
  const glm::vec3 d = glm::normalize(glm::vec3(0.08f, -0.05f, -1.0f));
  ShadedSample b = tracer.trace(Ray{{0.0f, 0.0f, 0.0f}, d}, &stats);
  ASSERT_TRUE(b.hit);
  expect_near3(b.position, d * (4.5f / std::abs(d.z)), 1e-5f, "oblique");

  // From the side: the face x = +0.5.
  ShadedSample c = tracer.trace(Ray{{3.0f, 0.1f, -5.2f}, {-1.0f, 0.0f, 0.0f}}, &stats);
  ASSERT_TRUE(c.hit);
  expect_near3(c.position, {0.5f, 0.1f, -5.2f}, 1e-5f, "side");
  EXPECT_EQ(stats.primary_rays, 3u);
  EXPECT_EQ(stats.sanitized, 0u);
}

TEST(TracerTest, MissReturnsBackgroundAndRayDirection) {
  Scene s;
  s.background = glm::vec3(0.2f, 0.3f, 0.9f);
  add_mesh_node(&s, box_mesh(glm::vec3(0.5f), -1), glm::dvec3(0.0, 0.0, -5.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const glm::vec3 d = glm::normalize(glm::vec3(0.3f, 0.4f, 1.0f));
  const ShadedSample m = tracer.trace(Ray{{0.0f, 0.0f, 0.0f}, d}, &stats);
  EXPECT_FALSE(m.hit);
  EXPECT_EQ(m.object_id, ShadedSample::kNoObject);
  EXPECT_EQ(m.color, s.background);
  EXPECT_EQ(m.position, d);
  EXPECT_EQ(m.velocity, glm::vec3(0.0f));
}

TEST(TracerTest, OccludedSeesBlockersButNotTheEndpoints) {
  Scene s;
  add_mesh_node(&s, box_mesh(glm::vec3(0.5f), -1), glm::dvec3(0.0, 0.0, -5.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  EXPECT_TRUE(tracer.occluded({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -10.0f}, &stats));
  EXPECT_FALSE(tracer.occluded({2.0f, 0.0f, 0.0f}, {2.0f, 0.0f, -10.0f}, &stats));
  // Stops short of the box.
  EXPECT_FALSE(tracer.occluded({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -4.0f}, &stats));
  // A point on the box's front face sees the eye; one on its back face does not.
  EXPECT_FALSE(tracer.occluded({0.1f, 0.1f, -4.5f}, {0.0f, 0.0f, 0.0f}, &stats));
  EXPECT_TRUE(tracer.occluded({0.1f, 0.1f, -5.5f}, {0.0f, 0.0f, 0.0f}, &stats));
  EXPECT_EQ(stats.occlusion_rays, 5u);
}

// ---------------------------------------------------------------------------------------------
// Lights and shadows

// A floor y = 0 ([-5, 5]^2), a point light 4 above the origin and a small occluder halfway.
struct ShadowScene {
  Scene s;
  glm::vec3 base{0.8f, 0.6f, 0.4f};
  glm::vec3 ambient{0.1f, 0.1f, 0.1f};
  float intensity = 10.0f;

  explicit ShadowScene(Light light, glm::dquat rotation = glm::dquat(1.0, 0.0, 0.0, 0.0)) {
    s.ambient = ambient;
    const int floor = add_material(&s, base, 0.0f, 1.0f);
    const int dark = add_material(&s, glm::vec3(0.1f), 0.0f, 1.0f);
    s.materials[size_t(dark)].double_sided = true;
    add_mesh_node(&s, quad_mesh({-5, 0, 5}, {10, 0, 0}, {0, 0, -10}, floor));
    add_mesh_node(&s, quad_mesh({-0.5f, 2, 0.5f}, {1, 0, 0}, {0, 0, -1}, dark));
    light.intensity = intensity;
    add_light_node(&s, light, glm::dvec3(0.0, 4.0, 0.0), rotation);
    s.finalize();
  }
};

// The color of the floor point p of a ShadowScene lit by a white point light at (0, 4, 0):
// ambient plus Lambert with irradiance I cos / d^2 (or I cos without falloff).
glm::vec3 lambert_reference(const ShadowScene& sc, glm::vec3 p, bool lit, bool inverse_square) {
  const glm::vec3 to_light = glm::vec3(0.0f, 4.0f, 0.0f) - p;
  const float d2 = glm::dot(to_light, to_light);
  const float cos_theta = to_light.y / std::sqrt(d2);
  const float irradiance = sc.intensity * cos_theta / (inverse_square ? d2 : 1.0f);
  return sc.ambient * sc.base +
         (lit ? sc.base / std::numbers::pi_v<float> * irradiance : glm::vec3(0.0f));
}

TEST(TracerTest, ShadowRayIsBlockedByOccluder) {
  ShadowScene sc{Light{}};
  Tracer tracer(sc.s);
  TraceStats stats;
  const glm::vec3 eye(0.0f, 1.0f, 3.0f);
  // Behind the occluder: ambient only.
  const ShadedSample shadowed = tracer.trace(ray_to(eye, {0.0f, 0.0f, 0.0f}), &stats);
  ASSERT_TRUE(shadowed.hit);
  expect_near3(shadowed.color, sc.ambient * sc.base, 1e-5f, "shadowed");
  // Beside it: the shadow ray passes the occluder at x = 1.
  const glm::vec3 p(2.0f, 0.0f, 0.0f);
  const ShadedSample lit = tracer.trace(ray_to(eye, p), &stats);
  ASSERT_TRUE(lit.hit);
  expect_near3(lit.color, lambert_reference(sc, p, true, true), 1e-5f, "lit");
  EXPECT_EQ(stats.shadow_rays, 2u);

  // Without shadows the point behind the occluder is lit as well.
  TracerOptions no_shadows;
  no_shadows.shadows = false;
  Tracer unshadowed(sc.s, no_shadows);
  TraceStats stats2;
  const ShadedSample c = unshadowed.trace(ray_to(eye, {0.0f, 0.0f, 0.0f}), &stats2);
  expect_near3(c.color, lambert_reference(sc, {0.0f, 0.0f, 0.0f}, true, true), 1e-5f, "no shadows");
  EXPECT_EQ(stats2.shadow_rays, 0u);
}

TEST(TracerTest, LightWithoutFalloffAndLightRange) {
  const glm::vec3 eye(0.0f, 1.0f, 3.0f), p(2.0f, 0.0f, 0.0f);
  TraceStats stats;
  Light constant;
  constant.inverse_square_falloff = false;
  ShadowScene a{constant};
  expect_near3(Tracer(a.s).trace(ray_to(eye, p), &stats).color,
               lambert_reference(a, p, true, false), 1e-5f, "no falloff");

  Light short_range;
  short_range.range = 4.0f;  // the point is sqrt(20) = 4.47 away
  ShadowScene b{short_range};
  expect_near3(Tracer(b.s).trace(ray_to(eye, p), &stats).color,
               lambert_reference(b, p, false, true), 1e-6f, "beyond range");
}

// KHR_animation_pointer's properties reach the shading at each time: the light's intensity
// doubles and the floor's base color halves from 0 s to 1 s, the floor's emission grows with
// its animated strength; between and beyond the keys, as the channels interpolate and hold.
TEST(TracerTest, AnimatedLightAndMaterialPropertiesShadeAtEachTime) {
  ShadowScene sc{Light{}};
  auto channel = [](AnimatedProperty property, int index, std::vector<glm::dvec4> values) {
    PropertyChannel c;
    c.property = property;
    c.index = index;
    c.curve.times = {0.0, 1.0};
    c.curve.values = std::move(values);
    return c;
  };
  const glm::dvec4 base(sc.base, 1.0);
  sc.s.property_channels = {
      channel(AnimatedProperty::kLightIntensity, 0, {{10, 0, 0, 0}, {20, 0, 0, 0}}),
      channel(AnimatedProperty::kBaseColorFactor, 0, {base, base * glm::dvec4(0.5, 0.5, 0.5, 1)}),
      channel(AnimatedProperty::kEmissiveFactor, 0, {{0.5, 0.25, 0, 0}, {0.5, 0.25, 0, 0}}),
      channel(AnimatedProperty::kEmissiveStrength, 0, {{0, 0, 0, 0}, {2, 0, 0, 0}})};
  sc.s.finalize();
  EXPECT_EQ(sc.s.animated_materials(), std::vector<int>{0});
  EXPECT_TRUE(sc.s.is_animated());
  EXPECT_DOUBLE_EQ(sc.s.duration(), 1.0);
  Tracer tracer(sc.s);
  TraceStats stats;
  const glm::vec3 eye(0.0f, 1.0f, 3.0f), p(2.0f, 0.0f, 0.0f);
  const glm::vec3 at0 = lambert_reference(sc, p, true, true);
  expect_near3(tracer.trace(ray_to(eye, p), &stats).color, at0, 1e-5f, "t = 0");
  for (const double t : {0.5, 1.0, 3.0}) {
    tracer.set_time(t);
    const float s = float(std::min(t, 1.0));
    // Base color x (1 - s / 2); light x (1 + s); emission (0.5, 0.25, 0) x 2 s.
    ShadowScene want{Light{}};
    want.base *= 1.0f - 0.5f * s;
    want.intensity *= 1.0f + s;
    const glm::vec3 color =
        lambert_reference(want, p, true, true) + glm::vec3(0.5f, 0.25f, 0.0f) * (2.0f * s);
    expect_near3(tracer.trace(ray_to(eye, p), &stats).color, color, 1e-5f,
                 ("t = " + std::to_string(t)).c_str());
  }
  tracer.set_time(0.0);
  expect_near3(tracer.trace(ray_to(eye, p), &stats).color, at0, 1e-5f, "back at 0 s");
}

TEST(TracerTest, SpotLightConeAndDirectionalLight) {
  const glm::vec3 eye(0.0f, 1.0f, 3.0f);
  TraceStats stats;
  Light spot;
  spot.type = Light::Type::kSpot;
  spot.inner_cone_angle = 0.2f;
  spot.outer_cone_angle = 0.3f;
  ShadowScene a{spot, pointing_down()};
  TracerOptions no_shadows;
  no_shadows.shadows = false;
  Tracer ta(a.s, no_shadows);
  // Inside the inner cone a spot is a point light; at 0.46 rad off axis it gives nothing.
  const glm::vec3 inside(0.5f, 0.0f, 0.0f), outside(2.0f, 0.0f, 0.0f);
  expect_near3(ta.trace(ray_to(eye, inside), &stats).color,
               lambert_reference(a, inside, true, true), 1e-5f, "in the cone");
  expect_near3(ta.trace(ray_to(eye, outside), &stats).color,
               lambert_reference(a, outside, false, true), 1e-6f, "outside the cone");

  // A directional light shining down gives irradiance I everywhere it is not blocked.
  Light sun;
  sun.type = Light::Type::kDirectional;
  ShadowScene b{sun, pointing_down()};
  Tracer tb(b.s);
  const glm::vec3 q(2.0f, 0.0f, 1.0f);
  expect_near3(tb.trace(ray_to(eye, q), &stats).color,
               b.ambient * b.base + b.base / std::numbers::pi_v<float> * b.intensity, 1e-5f, "sun");
  expect_near3(tb.trace(ray_to(eye, {0.1f, 0.0f, 0.1f}), &stats).color, b.ambient * b.base, 1e-6f,
               "sun, shadowed");
}

TEST(TracerTest, SpecularHighlightOnlyWhereTheMaterialHasOne) {
  // A glossy dielectric floor seen in the mirror direction of the light is brighter than the
  // Lambert value; a fully rough one (roughness 1, metallic 0) is exactly Lambert.
  for (float roughness : {0.3f, 1.0f}) {
    ShadowScene sc{Light{}};
    sc.s.materials[0].roughness = roughness;
    TracerOptions o;
    o.shadows = false;
    Tracer tracer(sc.s, o);
    TraceStats stats;
    const glm::vec3 p(1.0f, 0.0f, 0.0f);
    const glm::vec3 eye(2.0f, 4.0f, 0.0f);  // the light (0, 4, 0) mirrored about x = 1
    const glm::vec3 c = tracer.trace(ray_to(eye, p), &stats).color;
    const glm::vec3 lambert = lambert_reference(sc, p, true, true);
    if (roughness == 1.0f) {
      expect_near3(c, lambert, 1e-5f, "rough");
    } else {
      EXPECT_GT(c.x, lambert.x + 0.01f);
      // The highlight is white: it adds the same amount to every channel.
      EXPECT_NEAR(c.x - lambert.x, c.z - lambert.z, 1e-4f);
    }
  }
}

// The color of a square of a white Lambertian material (metallic 0, roughness 1) as `dress`
// changes it, lit by a sun of intensity 3 from behind the camera and seen straight on
// (v = l = n).
glm::vec3 square_lit_straight_on_scene(const std::function<void(Scene*, Material*)>& dress) {
  Scene s;
  const int mat = add_material(&s, glm::vec3(1.0f), 0.0f, 1.0f);
  Material m = s.materials[size_t(mat)];
  dress(&s, &m);  // may add textures to s
  s.materials[size_t(mat)] = m;
  add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
  Light sun;
  sun.type = Light::Type::kDirectional;  // along -Z: from behind the camera
  sun.intensity = 3.0f;
  add_light_node(&s, sun, glm::dvec3(0.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  return tracer.trace(Ray{{0.2f, 0.1f, 0.0f}, {0, 0, -1}}, &stats).color;
}
glm::vec3 square_lit_straight_on(const std::function<void(Material*)>& dress) {
  return square_lit_straight_on_scene([&](Scene*, Material* m) { dress(m); });
}

// KHR_materials_specular: a black dielectric square lit and seen straight on (v = l = n, so
// Fresnel is F0 exactly) shows only its highlight, F0 x D x vis x the light. Against glTF's core
// (F0 0.04), the extension's color (1, 0.5, 0.25) at ior 1.5 tints it by that color, a factor of
// 0.5 halves it, a factor of 0 removes it.
TEST(TracerTest, SpecularFactorsSetTheDielectricHighlight) {
  auto highlight = [](bool extension, float factor, glm::vec3 color) {
    return square_lit_straight_on([&](Material* m) {
      m->base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
      m->roughness = 0.5f;
      m->has_specular_extension = extension;
      m->specular = factor;
      m->specular_color = color;
    });
  };
  const glm::vec3 core = highlight(false, 1.0f, glm::vec3(1.0f));
  ASSERT_GT(core.r, 0.0f);
  EXPECT_NEAR(core.g, core.r, 1e-6f);
  const glm::vec3 tinted = highlight(true, 1.0f, {1.0f, 0.5f, 0.25f});
  expect_near3(tinted / core.r, {1.0f, 0.5f, 0.25f}, 1e-5f, "tinted");
  expect_near3(highlight(true, 0.5f, glm::vec3(1.0f)) / core.r, glm::vec3(0.5f), 1e-5f, "half");
  expect_near3(highlight(true, 0.0f, glm::vec3(1.0f)), glm::vec3(0.0f), 0.0f, "none");
}

TEST(TracerTest, MirroredNodeKeepsItsFrontFace) {
  // glTF: under a transform with negative determinant, clockwise triangles face front. A
  // single-sided square facing +Z, mirrored in x, still faces +Z and is lit from there.
  glm::vec3 colors[2];
  for (int mirrored = 0; mirrored < 2; ++mirrored) {
    Scene s;
    const int mat = add_material(&s, glm::vec3(0.6f), 0.0f, 1.0f);
    const int node = add_mesh_node(&s, quad_mesh({-1, -1, -3}, {2, 0, 0}, {0, 2, 0}, mat));
    if (mirrored) s.nodes[size_t(node)].scale = glm::dvec3(-1.0, 1.0, 1.0);
    add_light_node(&s, Light{}, glm::dvec3(0.0, 0.0, 0.0));
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    const ShadedSample r = tracer.trace(Ray{{0.2f, 0.1f, 0.0f}, {0, 0, -1}}, &stats);
    ASSERT_TRUE(r.hit);
    colors[mirrored] = r.color;
  }
  EXPECT_GT(colors[0].x, 0.0f);
  expect_near3(colors[1], colors[0], 1e-3f, "mirrored");
}

// ---------------------------------------------------------------------------------------------
// Robustness

TEST(TracerTest, DegenerateTrianglesAndZeroNormalsNeverGiveNaN) {
  Scene s;
  s.ambient = glm::vec3(0.2f);
  const int mat = add_material(&s, glm::vec3(0.7f), 0.5f, 0.4f);
  s.materials[0].double_sided = true;
  Mesh mesh;
  // Left square: zero vertex normals. Right square: proper normals. Both in z = -3.
  Primitive zero = quad({-2, -1, -3}, {2, 0, 0}, {0, 2, 0}, mat);
  zero.normals.assign(4, glm::vec3(0.0f));
  mesh.primitives.push_back(zero);
  mesh.primitives.push_back(quad({0, -1, -3}, {2, 0, 0}, {0, 2, 0}, mat));
  // Degenerate triangles: collinear, a repeated vertex, and a sliver, in front of the squares.
  Primitive degenerate;
  degenerate.positions = {
      {-1, 0, -2}, {0, 0, -2}, {1, 0, -2}, {0.5f, 0.3f, -2}, {0.5f, 0.3f + 1e-7f, -2}};
  degenerate.normals = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 1}, {0, 0, 1}};
  degenerate.indices = {0, 1, 2, 3, 3, 1, 0, 3, 4};
  degenerate.material = mat;
  mesh.primitives.push_back(degenerate);
  add_mesh_node(&s, mesh);
  Light light;
  add_light_node(&s, light, glm::dvec3(0.0, 0.0, 1.0));
  s.finalize();

  Tracer tracer(s);
  TraceStats stats;
  for (int j = 0; j < 41; ++j) {
    for (int i = 0; i < 81; ++i) {
      const glm::vec3 target(-2.0f + 0.05f * float(i), -1.0f + 0.05f * float(j), -3.0f);
      for (glm::vec3 eye : {glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(0.0f, 0.0f, -6.0f)}) {
        const ShadedSample r = tracer.trace(ray_to(eye, target), &stats);
        ASSERT_TRUE(finite(r.color) && finite(r.position) && finite(r.velocity)) << i << "," << j;
      }
    }
  }
  EXPECT_EQ(stats.sanitized, 0u);  // guarded, not repaired after the fact

  // A zero normal falls back to the geometric one: mirror-image points of the two squares
  // (symmetric about x = 0, like the light) shade alike.
  const glm::vec3 eye(0.0f, 0.0f, 1.0f);
  const glm::vec3 left = tracer.trace(ray_to(eye, {-0.7f, -0.4f, -3.0f}), &stats).color;
  const glm::vec3 right = tracer.trace(ray_to(eye, {0.7f, -0.4f, -3.0f}), &stats).color;
  expect_near3(left, right, 1e-5f, "zero normal");
}

TEST(TracerTest, NonFiniteShadingIsSanitizedAndCounted) {
  Scene s;
  const int mat = add_material(&s, glm::vec3(0.5f), 0.0f, 1.0f);
  s.materials[size_t(mat)].emissive = glm::vec3(std::numeric_limits<float>::infinity(), 0, 0);
  add_mesh_node(&s, box_mesh(glm::vec3(0.5f), mat), glm::dvec3(0.0, 0.0, -5.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  const ShadedSample r = tracer.trace(Ray{{0, 0, 0}, {0, 0, -1}}, &stats);
  EXPECT_TRUE(r.hit);
  EXPECT_TRUE(finite(r.color));
  EXPECT_EQ(stats.sanitized, 1u);

  // NaN in a material is not taken for black: it is replaced and counted too.
  s.materials[size_t(mat)].emissive = glm::vec3(std::numeric_limits<float>::quiet_NaN());
  Tracer nan_tracer(s);
  const ShadedSample n = nan_tracer.trace(Ray{{0, 0, 0}, {0, 0, -1}}, &stats);
  EXPECT_TRUE(finite(n.color));
  EXPECT_EQ(stats.sanitized, 2u);

  // A broken ray gives a finite miss.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const ShadedSample m = tracer.trace(Ray{{0, 0, 0}, {nan, nan, nan}}, &stats);
  EXPECT_TRUE(finite(m.color) && finite(m.position) && finite(m.velocity));
}

// ---------------------------------------------------------------------------------------------
// Motion

// Adds a box node that slides from x = 0 to x = 2 and turns by 90 degrees about +Y over 2 s
// (linear keys: constant velocity (1, 0, 0), constant angular velocity pi/4 rad/s).
int add_moving_box(Scene* s, int material) {
  const int box = add_mesh_node(s, box_mesh(glm::vec3(0.5f), material), glm::dvec3(0, 0, -5));
  AnimationChannel move;
  move.node = box;
  move.path = AnimatedPath::kTranslation;
  move.times = {0.0, 2.0};
  move.values = {{0.0, 0.0, -5.0, 0.0}, {2.0, 0.0, -5.0, 0.0}};
  AnimationChannel turn;
  turn.node = box;
  turn.path = AnimatedPath::kRotation;
  turn.times = {0.0, 2.0};
  const double h = 0.25 * M_PI;                                                // half of 90 degrees
  turn.values = {{0.0, 0.0, 0.0, 1.0}, {0.0, std::sin(h), 0.0, std::cos(h)}};  // x y z w
  s->channels.push_back(move);
  s->channels.push_back(turn);
  return box;
}

// The moving box above a static floor.
struct MovingScene {
  Scene s;
  int box = -1;
  int floor = -1;
  const glm::vec3 linear_velocity{1.0f, 0.0f, 0.0f};
  const glm::vec3 angular_velocity{0.0f, std::numbers::pi_v<float> / 4.0f, 0.0f};

  MovingScene() {
    const int mat = add_material(&s, glm::vec3(0.5f), 0.0f, 1.0f);
    floor = add_mesh_node(&s, quad_mesh({-10, -1, 10}, {20, 0, 0}, {0, 0, -20}, mat));
    box = add_moving_box(&s, mat);
    s.finalize();
  }

  glm::vec3 center(double t) const { return glm::vec3(float(t), 0.0f, -5.0f); }
};

TEST(TracerTest, MovingNodeReportsRigidBodyVelocity) {
  MovingScene ms;
  Tracer tracer(ms.s);
  TraceStats stats;
  // Inside the keyframe range and at both of its ends, where the difference quotient is one-
  // sided (a central one would straddle the clamped state and report half the velocity); the
  // one-sided quotient's error on the turning box is ~omega^2 dt |p - c| / 2 < 1e-3.
  for (const double t : {1.0, 0.0, 2.0}) {
    SCOPED_TRACE(t);
    const float tol = t == 1.0 ? 1e-4f : 1e-3f;
    tracer.set_time(t);
    EXPECT_EQ(tracer.time(), t);
    for (glm::vec3 o : {glm::vec3(0.1f, 0.1f, 0.0f), glm::vec3(-0.2f, -0.2f, 0.0f),
                        glm::vec3(0.3f, 0.3f, 0.0f)}) {
      const ShadedSample r =
          tracer.trace(Ray{o + glm::vec3(float(t), 0.0f, 0.0f), {0.0f, 0.0f, -1.0f}}, &stats);
      ASSERT_TRUE(r.hit);
      EXPECT_EQ(r.object_id, uint32_t(ms.box));
      // The hit point is on the surface of the box turned by 45 degrees per second.
      const glm::vec3 local =
          glm::angleAxis(-0.25f * std::numbers::pi_v<float> * float(t), glm::vec3(0, 1, 0)) *
          (r.position - ms.center(t));
      EXPECT_NEAR(std::max(std::abs(local.x), std::abs(local.z)), 0.5f, 1e-4f);
      // Rigid body: v = v_center + omega x (p - center).
      const glm::vec3 expected =
          ms.linear_velocity + glm::cross(ms.angular_velocity, r.position - ms.center(t));
      expect_near3(r.velocity, expected, tol, "velocity");
    }
  }
  // The static floor does not move.
  const ShadedSample f = tracer.trace(Ray{{5, 0, 0}, {0, -1, 0}}, &stats);
  ASSERT_TRUE(f.hit);
  EXPECT_EQ(f.object_id, uint32_t(ms.floor));
  EXPECT_EQ(f.velocity, glm::vec3(0.0f));
}

TEST(TracerTest, SetTimeMovesTheHitPoint) {
  MovingScene ms;
  Tracer tracer(ms.s);
  TraceStats stats;
  const Ray at_start{{0.1f, 0.1f, 0.0f}, {0.0f, 0.0f, -1.0f}};
  const Ray at_end{{2.1f, 0.1f, 0.0f}, {0.0f, 0.0f, -1.0f}};
  ShadedSample a = tracer.trace(at_start, &stats);
  ASSERT_TRUE(a.hit);
  EXPECT_EQ(a.object_id, uint32_t(ms.box));
  expect_near3(a.position, {0.1f, 0.1f, -4.5f}, 1e-5f, "t = 0");
  EXPECT_FALSE(tracer.trace(at_end, &stats).object_id == uint32_t(ms.box));

  tracer.set_time(2.0);  // the box is at x = 2, turned by 90 degrees (again axis-aligned)
  EXPECT_FALSE(tracer.trace(at_start, &stats).object_id == uint32_t(ms.box));
  ShadedSample b = tracer.trace(at_end, &stats);
  ASSERT_TRUE(b.hit);
  EXPECT_EQ(b.object_id, uint32_t(ms.box));
  expect_near3(b.position, {2.1f, 0.1f, -4.5f}, 1e-4f, "t = 2");

  tracer.set_time(0.0);  // and back
  expect_near3(tracer.trace(at_start, &stats).position, {0.1f, 0.1f, -4.5f}, 1e-5f, "back");
}

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

// A one-texel texture of (linear) value `texel` appended to s; returns its index.
int add_texel(Scene* s, glm::vec3 texel) {
  Texture t;
  t.width = t.height = 1;
  t.texels = {texel};
  s->textures.push_back(t);
  return int(s->textures.size()) - 1;
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

// ---------------------------------------------------------------------------------------------
// Crosshairs and threads

// A lit, partly glossy scene with a moving box for comparisons between query paths.
Scene busy_scene() {
  Scene s;
  s.ambient = glm::vec3(0.1f);
  s.background = glm::vec3(0.3f, 0.4f, 0.5f);
  const int mat = add_material(&s, glm::vec3(0.5f), 0.0f, 0.5f);
  add_mesh_node(&s, quad_mesh({-10, -1, 10}, {20, 0, 0}, {0, 0, -20}, mat));
  add_moving_box(&s, mat);
  const int mirror = add_material(&s, glm::vec3(0.9f), 1.0f, 0.05f);
  s.meshes.push_back(box_mesh(glm::vec3(0.7f), mirror));
  Node n;
  n.mesh = int(s.meshes.size()) - 1;
  n.translation = glm::dvec3(-2.0, 0.0, -6.0);
  s.nodes.push_back(n);
  s.roots.push_back(int(s.nodes.size()) - 1);
  add_light_node(&s, Light{}, glm::dvec3(1.0, 4.0, -2.0));
  s.finalize();
  return s;
}

void expect_same_sample(const ShadedSample& a, const ShadedSample& b, float tol) {
  EXPECT_EQ(a.hit, b.hit);
  EXPECT_EQ(a.object_id, b.object_id);
  expect_near3(a.color, b.color, tol, "color");
  expect_near3(a.position, b.position, tol, "position");
  expect_near3(a.velocity, b.velocity, tol, "velocity");
}

// ---------------------------------------------------------------------------------------------
// Glass (KHR_materials_transmission, KHR_materials_ior)

int add_glass(Scene* s, float ior, bool double_sided = false) {
  const int m = add_material(s, glm::vec3(1.0f), 0.0f, 0.0f);
  s->materials[size_t(m)].transmission = 1.0f;
  s->materials[size_t(m)].ior = ior;
  s->materials[size_t(m)].double_sided = double_sided;
  return m;
}

int add_emitter(Scene* s, glm::vec3 emission) {
  const int m = add_material(s, glm::vec3(0.0f), 0.0f, 1.0f);
  s->materials[size_t(m)].emissive = emission;
  return m;
}

// Schlick's Fresnel reflectance of a dielectric of index `ior` at cosine c (outer side).
double schlick(double ior, double c) {
  const double f0 = (ior - 1.0) * (ior - 1.0) / ((ior + 1.0) * (ior + 1.0));
  return f0 + (1.0 - f0) * std::pow(1.0 - c, 5.0);
}

// A slab of glass (ior 1.5, 1 thick, between z = 0.5 and z = -0.5) and, at depth z_target, a
// tiny red emitter where the closed form puts a ray that entered the top at 40 degrees: the
// ray leaves parallel to its entry direction, shifted by h (tan theta - tan theta_t) in x. A
// green emitter sits where the ray would land undeflected. Both emitters are 0.01 wide.
TEST(TracerTest, RayThroughAGlassSlabLeavesParallelAndDisplaced) {
  const double ior = 1.5, h = 1.0;
  const double theta = 40.0 * M_PI / 180.0;
  const double theta_t = std::asin(std::sin(theta) / ior);  // Snell
  const glm::vec3 d(float(std::sin(theta)), 0.0f, -float(std::cos(theta)));
  const glm::vec3 origin = glm::vec3(0.0f, 0.0f, 0.5f) - 2.0f * d;  // enters the top at x = 0
  for (double z_target : {-3.0, -8.0}) {
    const double below = -0.5 - z_target;
    const double x_refracted = h * std::tan(theta_t) + below * std::tan(theta);
    const double x_straight = (h + below) * std::tan(theta);
    ASSERT_GT(x_straight - x_refracted, 0.3);  // the two targets are far apart
    Scene s;
    add_mesh_node(&s, box_mesh({50.0f, 50.0f, 0.5f}, add_glass(&s, float(ior))));
    const float w = 0.01f;
    add_mesh_node(&s, quad_mesh({float(x_refracted) - w / 2, -w / 2, float(z_target)}, {w, 0, 0},
                                {0, w, 0}, add_emitter(&s, {1, 0, 0})));
    add_mesh_node(&s, quad_mesh({float(x_straight) - w / 2, -w / 2, float(z_target)}, {w, 0, 0},
                                {0, w, 0}, add_emitter(&s, {0, 1, 0})));
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    const ShadedSample out = tracer.trace(Ray{origin, d}, &stats);
    // Entering and leaving see the same outer angle, so the same Fresnel term; every other
    // path within the depth limit ends in the black background.
    const double t = 1.0 - schlick(ior, std::cos(theta));
    EXPECT_NEAR(out.color.r, t * t, 1e-4) << "target at z = " << z_target;
    EXPECT_EQ(out.color.g, 0.0f);
    EXPECT_TRUE(finite(out.color));
    EXPECT_EQ(stats.sanitized, 0u);
  }
}

// KHR_materials_volume: the slab of the test above, filled (thickness > 0), keeps its
// attenuation color per attenuation distance over the path inside it, L = h / cos(theta_t):
// the color (1, 0.25, 1) per 2 units keeps 0.25^(L / 2) of a white emitter's green and all of
// its red and blue; as a thin wall (thickness 0) the slab keeps all.
TEST(TracerTest, GlassVolumeAttenuatesByTheDistanceInside) {
  const double ior = 1.5, h = 1.0;
  const double theta = 40.0 * M_PI / 180.0;
  const double theta_t = std::asin(std::sin(theta) / ior);
  const glm::vec3 d(float(std::sin(theta)), 0.0f, -float(std::cos(theta)));
  const glm::vec3 origin = glm::vec3(0.0f, 0.0f, 0.5f) - 2.0f * d;
  const double z_target = -3.0;
  const double x_refracted = h * std::tan(theta_t) + (-0.5 - z_target) * std::tan(theta);
  const auto seen = [&](float thickness) {
    Scene s;
    const int glass = add_glass(&s, float(ior));
    s.materials[size_t(glass)].thickness = thickness;
    s.materials[size_t(glass)].attenuation_color = {1.0f, 0.25f, 1.0f};
    s.materials[size_t(glass)].attenuation_distance = 2.0f;
    add_mesh_node(&s, box_mesh({50.0f, 50.0f, 0.5f}, glass));
    const float w = 0.01f;
    add_mesh_node(&s, quad_mesh({float(x_refracted) - w / 2, -w / 2, float(z_target)}, {w, 0, 0},
                                {0, w, 0}, add_emitter(&s, {1, 1, 1})));
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    return tracer.trace(Ray{origin, d}, &stats).color;
  };
  const double t = 1.0 - schlick(ior, std::cos(theta));
  const double inside = h / std::cos(theta_t);
  const glm::vec3 thin = seen(0.0f);
  EXPECT_NEAR(thin.r, t * t, 1e-4);
  EXPECT_NEAR(thin.g, t * t, 1e-4);
  const glm::vec3 filled = seen(1.0f);
  EXPECT_NEAR(filled.r, t * t, 1e-4);
  EXPECT_NEAR(filled.b, t * t, 1e-4);
  EXPECT_NEAR(filled.g, t * t * std::pow(0.25, inside / 2.0), 1e-4);
}

// Nested media (KHR_materials_volume): a slab of water (ior 1.33, 1 thick) inside a slab of glass
// (ior 1.5, 2 thick: walls 0.5 thick above and below the water), both absorbing. A ray entering
// the top at 40 degrees bends at each interface by the ratio of the iors on its two sides
// (Snell: sin theta_0 = 1.5 sin theta_glass = 1.33 sin theta_water), so it lands below where the
// closed form puts it; it keeps 1 - F at each of the four interfaces, F Schlick's of the two
// iors at the cosine on the lower index's side, and the absorption of the medium it is in over
// each stretch: the glass's in both walls, the water's (the innermost) in the water.
TEST(TracerTest, NestedVolumesRefractByTheRatioOfTheirIorsAndAbsorbByTheInnermost) {
  const double n_glass = 1.5, n_water = 1.33, wall = 0.5, water = 1.0;
  const double theta = 40.0 * M_PI / 180.0;
  const double theta_glass = std::asin(std::sin(theta) / n_glass);
  const double theta_water = std::asin(std::sin(theta) / n_water);
  const glm::vec3 d(float(std::sin(theta)), 0.0f, -float(std::cos(theta)));
  const float top = float(wall + water / 2);
  const glm::vec3 origin = glm::vec3(0.0f, 0.0f, top) - 2.0f * d;  // enters the top at x = 0
  const double z_target = -3.0;
  const double x_target = 2 * wall * std::tan(theta_glass) + water * std::tan(theta_water) +
                          (-top - z_target) * std::tan(theta);
  const glm::vec3 glass_color(0.5f, 0.8f, 1.0f), water_color(1.0f, 0.6f, 0.3f);  // per 2 units
  Scene s;
  const int glass = add_glass(&s, float(n_glass));
  const int liquid = add_glass(&s, float(n_water));
  for (const auto& [material, color] : {std::pair(glass, glass_color), {liquid, water_color}}) {
    Material& m = s.materials[size_t(material)];
    m.thickness = 1.0f;
    m.attenuation_color = color;
    m.attenuation_distance = 2.0f;
  }
  add_mesh_node(&s, box_mesh({50.0f, 50.0f, top}, glass));
  add_mesh_node(&s, box_mesh({49.0f, 49.0f, float(water / 2)}, liquid));
  const float w = 0.01f;
  add_mesh_node(&s, quad_mesh({float(x_target) - w / 2, -w / 2, float(z_target)}, {w, 0, 0},
                              {0, w, 0}, add_emitter(&s, {1, 1, 1})));
  s.finalize();
  TracerOptions o;
  o.max_mirror_depth = 4;  // four refractions
  Tracer tracer(s, o);
  TraceStats stats;
  const ShadedSample out = tracer.trace(Ray{origin, d}, &stats);
  const double f_air = schlick(n_glass, std::cos(theta));
  const double f0_water = std::pow((n_glass - n_water) / (n_glass + n_water), 2.0);
  const double f_water = f0_water + (1.0 - f0_water) * std::pow(1.0 - std::cos(theta_water), 5.0);
  const double fresnel = std::pow((1.0 - f_air) * (1.0 - f_water), 2.0);
  for (int c = 0; c < 3; ++c) {
    const double kept = std::pow(glass_color[c], 2 * wall / std::cos(theta_glass) / 2.0) *
                        std::pow(water_color[c], water / std::cos(theta_water) / 2.0);
    EXPECT_NEAR(out.color[c], fresnel * kept, 1e-4) << "channel " << c;
  }
  EXPECT_EQ(stats.sanitized, 0u);
}

// KHR_materials_dispersion: in a slab of glass 4 thick (a volume), each color channel refracts
// with its own ior, 1.5 -/+ (1.5 - 1) / (2 V_d) for red and blue, and so leaves displaced by its
// own h (tan theta - tan theta_c). A tiny white emitter where one channel lands lights that
// channel alone, by its own Fresnel terms; without dispersion, or in a thin wall (thickness 0),
// where the rays do not split, the emitter under green's path lights all three.
TEST(TracerTest, DispersionRefractsEachColorChannelWithItsOwnIor) {
  const double ior = 1.5, h = 4.0, dispersion = 2.0;  // V_d = 10: an exaggerated glass
  const double half_spread = (ior - 1.0) / (2.0 * (20.0 / dispersion));
  const double theta = 40.0 * M_PI / 180.0;
  const glm::vec3 d(float(std::sin(theta)), 0.0f, -float(std::cos(theta)));
  const glm::vec3 origin = glm::vec3(0.0f, 0.0f, float(h / 2)) - 2.0f * d;
  const double z_target = -h / 2 - 2.0;
  const auto landing = [&](double ior_c) {
    return h * std::tan(std::asin(std::sin(theta) / ior_c)) + 2.0 * std::tan(theta);
  };
  const auto seen = [&](double x_target, float thickness, float disp) {
    Scene s;
    const int glass = add_glass(&s, float(ior));
    s.materials[size_t(glass)].thickness = thickness;
    s.materials[size_t(glass)].dispersion = disp;
    add_mesh_node(&s, box_mesh({50.0f, 50.0f, float(h / 2)}, glass));
    const float w = 0.01f;
    add_mesh_node(&s, quad_mesh({float(x_target) - w / 2, -w / 2, float(z_target)}, {w, 0, 0},
                                {0, w, 0}, add_emitter(&s, {1, 1, 1})));
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    const ShadedSample out = tracer.trace(Ray{origin, d}, &stats);
    EXPECT_EQ(stats.sanitized, 0u);
    return out.color;
  };
  const double iors[3] = {ior - half_spread, ior, ior + half_spread};
  ASSERT_GT(landing(iors[0]) - landing(iors[1]), 0.03);  // the channels land 3 widths apart
  ASSERT_GT(landing(iors[1]) - landing(iors[2]), 0.03);
  for (int c = 0; c < 3; ++c) {
    const glm::vec3 color = seen(landing(iors[c]), 1.0f, float(dispersion));
    const double t = 1.0 - schlick(iors[c], std::cos(theta));  // in and out at the same angle
    for (int k = 0; k < 3; ++k) {
      if (k == c) {
        EXPECT_NEAR(color[k], t * t, 1e-4) << "channel " << c;
      } else {
        EXPECT_EQ(color[k], 0.0f) << "channel " << k << " at channel " << c << "'s landing";
      }
    }
  }
  const double t = 1.0 - schlick(ior, std::cos(theta));
  for (const glm::vec3& color : {seen(landing(ior), 1.0f, 0.0f), seen(landing(ior), 0.0f, 2.0f)}) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(color[k], t * t, 1e-4) << "channel " << k;
  }
}

// A ray inside a slab of ior 1.5 meets its faces at the angle it starts with: below the
// critical angle asin(1 / 1.5) = 41.81 degrees it leaves (and lights up the emitter below);
// beyond it every bounce reflects totally, nothing leaves, and the depth limit ends the chain.
TEST(TracerTest, TotalInternalReflectionBeyondTheCriticalAngle) {
  const double critical = std::asin(1.0 / 1.5) * 180.0 / M_PI;
  for (bool double_sided : {false, true}) {
    Scene s;
    add_mesh_node(&s, box_mesh({50.0f, 50.0f, 0.5f}, add_glass(&s, 1.5f, double_sided)));
    add_mesh_node(
        &s, quad_mesh({-100, -100, -3}, {200, 0, 0}, {0, 200, 0}, add_emitter(&s, {1, 0, 0})));
    add_mesh_node(&s,
                  quad_mesh({-100, -100, 3}, {0, 200, 0}, {200, 0, 0}, add_emitter(&s, {0, 1, 0})));
    s.finalize();
    Tracer tracer(s);
    for (double degrees : {critical - 1.0, critical + 1.0}) {
      const double a = degrees * M_PI / 180.0;
      const Ray ray{{0, 0, 0}, {float(std::sin(a)), 0.0f, -float(std::cos(a))}};
      TraceStats stats;
      const ShadedSample out = tracer.trace(ray, &stats);
      EXPECT_TRUE(finite(out.color));
      if (degrees < critical) {
        // Leaves through the bottom with 1 - F (F at the refracted angle's cosine), and once
        // more after reflecting off the bottom and the top (F^2 (1 - F)); the depth limit
        // ends the rest.
        const double sin_t = 1.5 * std::sin(a);
        const double F = schlick(1.5, std::sqrt(1.0 - sin_t * sin_t));
        const double expected = (1.0 - F) * (1.0 + F * F);
        EXPECT_NEAR(out.color.r, expected, 1e-3) << degrees << " double-sided " << double_sided;
      } else {
        EXPECT_EQ(out.color, glm::vec3(0.0f)) << degrees << " double-sided " << double_sided;
        EXPECT_EQ(stats.reflection_rays, uint64_t(TracerOptions().max_mirror_depth));
      }
    }
  }
}

// transmissionFactor 0 is opaque, whatever the ior: the same samples and rays as a material
// without either extension.
TEST(TracerTest, TransmissionZeroTracesAsBefore) {
  const Scene plain = busy_scene();
  Scene with_ior = plain;
  for (Material& m : with_ior.materials) {
    m.transmission = 0.0f;
    m.ior = 1.2f;
  }
  Tracer a(plain), b(with_ior);
  TraceStats sa, sb;
  for (int k = 0; k < 64; ++k) {
    const glm::vec3 to(float(k % 8) - 3.5f, float(k / 8) - 3.5f, -2.0f);
    const Ray ray = ray_to({0.3f, 0.2f, 6.0f}, to);
    const ShadedSample x = a.trace(ray, &sa), y = b.trace(ray, &sb);
    EXPECT_EQ(x.color, y.color) << k;
  }
  EXPECT_EQ(sa.reflection_rays, sb.reflection_rays);
  EXPECT_EQ(sa.shadow_rays, sb.shadow_rays);
}

// KHR_materials_transmission's texture multiplies its factor: glass whose transmission texel is
// 0.25 shows what glass of transmission 0.25 does (the rest of its light diffuse).
TEST(TracerTest, TransmissionTextureMultipliesTheFactor) {
  // Glass in front of an emitter, seen straight through.
  const auto through_glass = [](float factor, bool texture) {
    Scene s;
    const int glass = add_glass(&s, 1.5f);
    if (texture) s.materials[size_t(glass)].transmission_texture = add_texel(&s, glm::vec3(factor));
    s.materials[size_t(glass)].transmission = texture ? 1.0f : factor;
    s.materials[size_t(glass)].base_color_factor = glm::vec4(0.6f, 0.6f, 0.6f, 1.0f);
    add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, glass));
    add_mesh_node(&s, quad_mesh({-5, -5, -4}, {10, 0, 0}, {0, 10, 0},
                                add_emitter(&s, glm::vec3(1.0f, 0.5f, 0.25f))));
    s.ambient = glm::vec3(0.5f);
    s.finalize();
    Tracer tracer(s);
    TraceStats stats;
    return tracer.trace(Ray{{0.2f, 0.1f, 0.0f}, {0, 0, -1}}, &stats).color;
  };
  expect_near3(through_glass(0.25f, true), through_glass(0.25f, false), 1e-6f, "transmission");
  ASSERT_GT(std::abs(through_glass(0.25f, false).r - through_glass(1.0f, false).r), 1e-2f);
}

// Shadows through glass (a filter shadow): a floor lit by a sun straight above, under a box of
// glass between y = 1 and y = 2. A shadow ray crosses the box's bottom and top, each keeping
// transmission x base color, so the floor below gets the sun times base^2 (a clear box: all of
// it; an opaque box: none; a glass of transmission 0.5, tinted: (0.5 base)^2 per channel, the
// same where textures give the transmission and the tint), beside the box the whole sun. A box
// that transmits diffusely (KHR_materials_diffuse_transmission) lets it through the same way,
// each surface keeping strength x color x what glass leaves of the diffuse part, and a box of
// both adds the two. The crosshair's 8-wide shadow packets agree with single rays, and the
// sampler's occlusion rays still stop at the box (it is a visible surface).
TEST(TracerTest, ShadowRaysPassThroughGlassDimmedByEachSurface) {
  const glm::vec3 floor_base(0.8f, 0.6f, 0.4f);
  const float intensity = 3.0f;
  struct Case {
    const char* name;
    float transmission;
    glm::vec3 base;
    float diffuse;  // diffuse transmission's strength, and its color
    glm::vec3 diffuse_color;
    glm::vec3 kept;  // what the two surfaces keep of the sun
    bool textures;   // the factors above as textures, the factors 1 (white)
  };
  const glm::vec3 tint(1.0f, 0.5f, 0.25f), gray(0.5f);
  const Case cases[] = {
      {"clear", 1.0f, glm::vec3(1.0f), 0.0f, gray, glm::vec3(1.0f), false},
      {"tinted", 0.5f, tint, 0.0f, gray, glm::vec3(0.25f, 0.0625f, 0.015625f),
       false},  // (0.5 base)^2
      {"tinted by textures", 0.5f, tint, 0.0f, gray, glm::vec3(0.25f, 0.0625f, 0.015625f), true},
      {"opaque", 0.0f, glm::vec3(1.0f), 0.0f, gray, glm::vec3(0.0f), false},
      // (0.5 color)^2
      {"diffuse transmission", 0.0f, gray, 0.5f, tint, glm::vec3(0.25f, 0.0625f, 0.015625f), false},
      {"diffuse transmission by textures", 0.0f, gray, 0.5f, tint,
       glm::vec3(0.25f, 0.0625f, 0.015625f), true},
      // (0.5 base + 0.5 x gray x (1 - 0.5))^2 = (0.625, 0.375, 0.25)^2
      {"glass and diffuse transmission", 0.5f, tint, 0.5f, gray,
       glm::vec3(0.390625f, 0.140625f, 0.0625f), false},
      {"glass and diffuse transmission by textures", 0.5f, tint, 0.5f, gray,
       glm::vec3(0.390625f, 0.140625f, 0.0625f), true},
  };
  for (const Case& c : cases) {
    for (bool packet : {true, false}) {
      SCOPED_TRACE(std::string(c.name) + (packet ? ", packets" : ", single rays"));
      Scene s;
      const int floor = add_material(&s, floor_base, 0.0f, 1.0f);
      add_mesh_node(&s, quad_mesh({-5, 0, 5}, {10, 0, 0}, {0, 0, -10}, floor));
      const int glass = add_material(&s, c.textures ? glm::vec3(1.0f) : c.base, 0.0f, 0.0f);
      Material& m = s.materials[size_t(glass)];
      m.transmission = c.textures ? 1.0f : c.transmission;
      m.diffuse_transmission = c.textures && c.diffuse > 0.0f ? 1.0f : c.diffuse;
      m.diffuse_transmission_color = c.textures ? glm::vec3(1.0f) : c.diffuse_color;
      if (c.textures) {
        m.base_color_texture = add_texel(&s, c.base);
        m.transmission_texture = add_texel(&s, glm::vec3(c.transmission, 0.0f, 0.0f));  // red
        if (c.diffuse > 0.0f) {
          // (The loader holds the strength image's alpha in red.)
          m.diffuse_transmission_texture = add_texel(&s, glm::vec3(c.diffuse, 0.0f, 0.0f));
          m.diffuse_transmission_color_texture = add_texel(&s, c.diffuse_color);
        }
      }
      s.materials[size_t(glass)].ior = 1.5f;
      add_mesh_node(&s, box_mesh({2.0f, 0.5f, 2.0f}, glass), glm::dvec3(0.0, 1.5, 0.0));
      Light sun;
      sun.type = Light::Type::kDirectional;
      sun.intensity = intensity;
      add_light_node(&s, sun, {0, 5, 0}, pointing_down());
      s.finalize();
      TracerOptions o;
      o.packet_crosshair = packet;
      Tracer tracer(s, o);
      // Seen from the side, below the box: the view does not cross the glass.
      const Camera cam = Camera::look_at({4.5, 0.6, 0.0}, {0.0, 0.0, 0.0}, {0, 1, 0}, 1.2, 0.01);
      const int w = 64, h = 48;
      const glm::vec3 lit = floor_base / std::numbers::pi_v<float> * intensity;
      TraceStats stats;
      int under = 0, beside = 0;
      for (int j = 1; j < h - 1; j += 2) {
        for (int i = 1; i < w - 1; i += 2) {
          std::array<ShadedSample, 5> cross;
          tracer.trace_crosshair(cam, i + 0.5, j + 0.5, w, h, &cross, &stats);
          const ShadedSample& x = cross[0];
          if (!x.hit || std::abs(x.position.y) > 1e-3f) continue;  // the floor only
          const bool shaded = std::abs(x.position.x) < 1.9f && std::abs(x.position.z) < 1.9f;
          const bool clear = std::abs(x.position.x) > 2.1f || std::abs(x.position.z) > 2.1f;
          if (!shaded && !clear) continue;  // the edge of the box's shadow
          expect_near3(x.color, shaded ? lit * c.kept : lit, 1e-4f, "floor");
          expect_same_sample(x, tracer.trace(cam.ray(i + 0.5, j + 0.5, w, h), &stats), 1e-4f);
          (shaded ? under : beside) += 1;
        }
      }
      EXPECT_GT(under, 30);
      EXPECT_GT(beside, 30);
      // The occlusion ray of the sampler: glass is a surface it sees.
      EXPECT_TRUE(tracer.occluded({0, 0.01f, 0}, {0, 4, 0}, &stats));
    }
  }
}

// KHR_materials_volume: a shadow ray keeps exp(-absorption x the length it travels inside
// absorbing glass), color^(length / attenuation distance), as a refracted ray does: through a
// clear box 1 thick (the sun straight down onto the floor under it), from a point inside it (a
// camera inside looking at a square 0.8 below the box's top, beside the shadow rays of the floor),
// and toward a point light inside
// it (0.5 of the way inside); a thin wall (thickness 0) absorbs nothing. Single rays and
// packets agree.
TEST(TracerTest, ShadowRaysThroughAVolumeAreAbsorbedByTheDistanceInside) {
  const glm::vec3 color(0.5f, 0.25f, 1.0f);
  const float distance = 2.0f;  // attenuationDistance
  const glm::vec3 floor_base(0.8f, 0.6f, 0.4f);
  const float pi = std::numbers::pi_v<float>;
  struct Setup {
    Scene s;
    int glass = -1;
  };
  const auto scene_with = [&](float thickness, const std::function<void(Scene*)>& light) {
    Setup u;
    const int floor = add_material(&u.s, floor_base, 0.0f, 1.0f);
    add_mesh_node(&u.s, quad_mesh({-5, 0, 5}, {10, 0, 0}, {0, 0, -10}, floor));
    add_mesh_node(&u.s, quad_mesh({0.5f, 1.2f, 0.5f}, {1, 0, 0}, {0, 0, -1}, floor));  // inside
    u.glass = add_material(&u.s, glm::vec3(1.0f), 0.0f, 0.0f);
    Material& g = u.s.materials[size_t(u.glass)];
    g.transmission = 1.0f;
    g.thickness = thickness;
    g.attenuation_color = color;
    g.attenuation_distance = distance;
    add_mesh_node(&u.s, box_mesh({2.0f, 0.5f, 2.0f}, u.glass), glm::dvec3(0.0, 1.5, 0.0));
    light(&u.s);
    u.s.finalize();
    return u;
  };
  const auto sun = [](Scene* s) {
    Light l;
    l.type = Light::Type::kDirectional;
    l.intensity = 3.0f;
    add_light_node(s, l, {0, 5, 0}, pointing_down());
  };
  const auto lamp = [](Scene* s) {
    Light l;
    l.intensity = 3.0f;
    add_light_node(s, l, {0, 1.5, 0});
  };
  // The floor under the box's middle, seen from beside it below the glass; and the square
  // inside, seen from inside.
  const Camera beside = Camera::look_at({4.5, 0.6, 0.0}, {0.0, 0.0, 0.0}, {0, 1, 0}, 1.2, 0.01);
  const Camera within = Camera::look_at({0.0, 1.8, 0.0}, {1.0, 1.2, 0.0}, {0, 1, 0}, 1.2, 0.01);
  const auto seen = [&](const Setup& u, const Camera& cam, bool packet) {
    TracerOptions o;
    o.packet_crosshair = packet;
    Tracer tracer(u.s, o);
    TraceStats stats;
    std::array<ShadedSample, 5> cross;
    tracer.trace_crosshair(cam, 32.0, 24.0, 64, 48, &cross, &stats);
    expect_same_sample(cross[0], tracer.trace(cam.ray(32.0, 24.0, 64, 48), &stats), 1e-4f);
    return cross[0];
  };
  const glm::vec3 lit = floor_base / pi * 3.0f;
  for (bool packet : {true, false}) {
    SCOPED_TRACE(packet ? "packets" : "single rays");
    const ShadedSample through = seen(scene_with(1.0f, sun), beside, packet);
    ASSERT_NEAR(through.position.y, 0.0f, 1e-3f);
    expect_near3(through.color, lit * glm::pow(color, glm::vec3(1.0f / distance)), 1e-3f,
                 "through the box");
    expect_near3(seen(scene_with(0.0f, sun), beside, packet).color, lit, 1e-4f, "thin wall");
    const ShadedSample from_inside = seen(scene_with(1.0f, sun), within, packet);
    ASSERT_NEAR(from_inside.position.y, 1.2f, 1e-3f);
    expect_near3(from_inside.color, lit * glm::pow(color, glm::vec3(0.8f / distance)), 1e-3f,
                 "from inside");
    const ShadedSample to_inside = seen(scene_with(1.0f, lamp), beside, packet);
    const glm::vec3 to_lamp = glm::vec3(0, 1.5f, 0) - to_inside.position;
    const float d2 = glm::dot(to_lamp, to_lamp);
    const float cosine = to_lamp.y / std::sqrt(d2);
    expect_near3(to_inside.color, lit / d2 * cosine * glm::pow(color, glm::vec3(0.5f / distance)),
                 1e-3f, "to a light inside");
  }
}

// Nested media on a shadow ray's way: a box of absorbing glass 1 high (y 1 to 2) holding a box
// 0.5 high (y 1.25 to 1.75) of another medium, the sun straight down. Each stretch keeps the
// absorption of the innermost medium there: the glass's over the 0.5 outside the inner box, the
// inner one's over its own 0.5; an inner medium that absorbs nothing (clear water in tinted
// glass) keeps all of its stretch. From a floor inside the inner box (at y 1.4), the ray starts
// in both media and leaves the inner one first. Single rays and packets agree.
TEST(TracerTest, ShadowRaysThroughNestedVolumesAreAbsorbedByTheInnermost) {
  const glm::vec3 outer_color(0.5f, 0.25f, 1.0f), inner_color(1.0f, 0.5f, 0.2f);
  const glm::vec3 floor_base(0.8f, 0.6f, 0.4f);
  const glm::vec3 lit = floor_base / std::numbers::pi_v<float> * 3.0f;
  // The glass's absorption keeps color^(length / 2) (attenuation distance 2).
  const auto kept = [](glm::vec3 color, float length) {
    return glm::pow(color, glm::vec3(length / 2.0f));
  };
  for (bool clear_inside : {false, true}) {
    Scene s;
    const int floor = add_material(&s, floor_base, 0.0f, 1.0f);
    add_mesh_node(&s, quad_mesh({-5, 0, 5}, {10, 0, 0}, {0, 0, -10}, floor));
    add_mesh_node(&s, quad_mesh({0.2f, 1.4f, 0.2f}, {0.4f, 0, 0}, {0, 0, -0.4f}, floor));
    int media[2];
    for (int k = 0; k < 2; ++k) {
      media[k] = add_material(&s, glm::vec3(1.0f), 0.0f, 0.0f);
      Material& g = s.materials[size_t(media[k])];
      g.transmission = 1.0f;
      g.thickness = 1.0f;
      if (k == 0 || !clear_inside) {
        g.attenuation_color = k == 0 ? outer_color : inner_color;
        g.attenuation_distance = 2.0f;
      }
    }
    add_mesh_node(&s, box_mesh({2.0f, 0.5f, 2.0f}, media[0]), glm::dvec3(0.0, 1.5, 0.0));
    add_mesh_node(&s, box_mesh({1.0f, 0.25f, 1.0f}, media[1]), glm::dvec3(0.0, 1.5, 0.0));
    Light sun;
    sun.type = Light::Type::kDirectional;
    sun.intensity = 3.0f;
    add_light_node(&s, sun, {0, 5, 0}, pointing_down());
    s.finalize();
    const glm::vec3 inner = clear_inside ? glm::vec3(1.0f) : inner_color;
    struct View {
      Camera camera;
      float floor_y;
      glm::vec3 expected;
      const char* what;
    };
    const View views[] = {
        {Camera::look_at({4.5, 0.6, 0.0}, {0.0, 0.0, 0.0}, {0, 1, 0}, 1.2, 0.01), 0.0f,
         lit * kept(outer_color, 0.5f) * kept(inner, 0.5f), "through both boxes"},
        {Camera::look_at({0.0, 1.6, 0.0}, {1.0, 1.0, 0.0}, {0, 1, 0}, 1.2, 0.01), 1.4f,
         lit * kept(inner, 0.35f) * kept(outer_color, 0.25f), "from inside the inner box"},
    };
    for (bool packet : {true, false}) {
      TracerOptions o;
      o.packet_crosshair = packet;
      Tracer tracer(s, o);
      for (const View& v : views) {
        SCOPED_TRACE(::testing::Message() << v.what << (packet ? ", packets" : ", single rays")
                                          << (clear_inside ? ", clear inner medium" : ""));
        TraceStats stats;
        std::array<ShadedSample, 5> cross;
        tracer.trace_crosshair(v.camera, 32.0, 24.0, 64, 48, &cross, &stats);
        ASSERT_NEAR(cross[0].position.y, v.floor_y, 1e-3f);
        expect_near3(cross[0].color, v.expected, 1e-3f, v.what);
        expect_same_sample(cross[0], tracer.trace(v.camera.ray(32.0, 24.0, 64, 48), &stats), 1e-4f);
      }
    }
  }
}

// A glass sphere-like box seen from many directions, on a lit floor: every sample is finite
// and a sample's secondary rays stay within 2 + 4 + ... + 2^depth (two per glass hit).
TEST(TracerTest, GlassSamplesAreFiniteAndBoundedInRays) {
  Scene s;
  s.background = glm::vec3(0.2f, 0.3f, 0.5f);
  s.ambient = glm::vec3(0.1f);
  add_mesh_node(&s, box_mesh({1.0f, 1.0f, 1.0f}, add_glass(&s, 1.5f, true)));
  add_mesh_node(&s, quad_mesh({-10, -2, 10}, {20, 0, 0}, {0, 0, -20},
                              add_material(&s, glm::vec3(0.7f), 0.0f, 0.5f)));
  Light sun;
  sun.type = Light::Type::kDirectional;
  add_light_node(&s, sun, {0, 5, 0}, pointing_down());
  s.finalize();
  Tracer tracer(s);
  const int depth = tracer.options().max_mirror_depth;
  uint64_t secondary = 0;
  for (int k = 0; k < 200; ++k) {
    const float a = float(k) * 0.0314f;
    const Ray ray = ray_to({4.0f * std::cos(a), 1.5f, 4.0f * std::sin(a)},
                           {0.3f * std::sin(3.0f * a), 0.2f, 0.0f});
    TraceStats stats;
    const ShadedSample out = tracer.trace(ray, &stats);
    EXPECT_TRUE(finite(out.color)) << k;
    EXPECT_EQ(stats.sanitized, 0u);
    EXPECT_LE(stats.reflection_rays, uint64_t((2 << depth) - 2));
    secondary += stats.reflection_rays;
  }
  EXPECT_GT(secondary, 200u);  // the rays do go through the glass
}

TEST(TracerTest, CrosshairEqualsFiveSingleRays) {
  const Scene s = busy_scene();
  for (bool packet : {true, false}) {
    TracerOptions o;
    o.packet_crosshair = packet;
    Tracer tracer(s, o);
    tracer.set_time(0.7);
    const Camera cam =
        Camera::look_at({0.0, 1.0, 3.0}, {0.0, -0.5, -5.0}, {0.0, 1.0, 0.0}, 0.9, 0.01);
    const int w = 64, h = 48;
    const double dx[5] = {0, -1, 1, 0, 0}, dy[5] = {0, 0, 0, -1, 1};
    TraceStats stats;
    for (int j = 1; j < h - 1; j += 3) {
      for (int i = 1; i < w - 1; i += 3) {
        const double x = i + 0.37, y = j + 0.61;
        std::array<ShadedSample, 5> cross;
        tracer.trace_crosshair(cam, x, y, w, h, &cross, &stats);
        for (int k = 0; k < 5; ++k) {
          const ShadedSample single = tracer.trace(cam.ray(x + dx[k], y + dy[k], w, h), &stats);
          expect_same_sample(cross[size_t(k)], single, 1e-4f);
        }
      }
    }
    EXPECT_EQ(stats.primary_rays % 10, 0u);
  }
}

// TracerOptions::embree_threads bounds the threads of Embree's builds and commits; the BVHs it
// builds may differ in layout, never in what a ray hits. A negative count is refused by name.
TEST(TracerTest, EmbreeThreadsChangeNoSample) {
  const Scene s = busy_scene();
  TracerOptions one;
  one.embree_threads = 1;
  Tracer single(s, one);
  Tracer every(s);
  const Camera cam = Camera::look_at({0.0, 1.0, 3.0}, {0.0, -0.5, -5.0}, {0, 1, 0}, 0.9, 0.01);
  const int w = 40, h = 30;
  TraceStats st;
  for (double t : {0.0, 0.7, 1.3}) {
    single.set_time(t);
    every.set_time(t);
    int hits = 0;
    for (int i = 0; i < w * h; ++i) {
      const Ray ray = cam.ray(i % w + 0.5, i / w + 0.5, w, h);
      const ShadedSample a = single.trace(ray, &st);
      expect_same_sample(a, every.trace(ray, &st), 1e-4f);
      hits += a.hit ? 1 : 0;
    }
    EXPECT_GT(hits, w * h / 2) << "t = " << t;
  }
  TracerOptions negative;
  negative.embree_threads = -1;
  try {
    Tracer bad(s, negative);
    ADD_FAILURE() << "a negative thread count was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("-1 Embree threads"), std::string::npos) << e.what();
  }
}

// Static nodes that share a mesh trace alike whether the tracer copies the mesh into world space
// for each (a few copies: the default) or instances it (TracerOptions::max_copied_vertices = 0,
// as for a forest of EXT_mesh_gpu_instancing copies): a box on five nodes (moved, turned,
// stretched, mirrored, and hidden by a scale of 0) over a floor, lit with shadows, a glass box
// on two more. Rays that cross a silhouette may land on either side of it in the two (float
// transforms of the ray or of the vertices): at most 1% of rays.
TEST(TracerTest, SharedStaticMeshesTraceAlikeCopiedOrInstanced) {
  Scene s;
  const int red = add_material(&s, glm::vec3(0.8f, 0.2f, 0.1f), 0.0f, 0.6f);
  const int grey = add_material(&s, glm::vec3(0.6f), 0.0f, 1.0f);
  const int glass = add_glass(&s, 1.5f);
  add_mesh_node(&s, quad_mesh({-6, -1, 2}, {12, 0, 0}, {0, 0, -14}, grey));
  const int box = add_mesh_node(&s, box_mesh({0.4f, 0.4f, 0.4f}, red), {-2.0, -0.5, -4.0});
  const int mesh = s.nodes[size_t(box)].mesh;
  const auto copy = [&](int m, glm::dvec3 t, glm::dquat r, glm::dvec3 scale) {
    Node n;
    n.mesh = m;
    n.translation = t;
    n.rotation = r;
    n.scale = scale;
    s.nodes.push_back(n);
    s.roots.push_back(int(s.nodes.size()) - 1);
  };
  const glm::dquat none(1.0, 0.0, 0.0, 0.0);
  copy(mesh, {0.0, -0.3, -5.0}, glm::angleAxis(0.6, glm::normalize(glm::dvec3(1, 1, 0))),
       {1, 1, 1});
  copy(mesh, {2.0, -0.2, -4.5}, none, {0.5, 2.0, 1.0});
  copy(mesh, {-0.8, 0.8, -6.0}, glm::angleAxis(0.3, glm::dvec3(0, 1, 0)), {-1.0, 1.0, 1.0});
  copy(mesh, {0.0, 0.0, -3.0}, none, {0.0, 0.0, 0.0});
  add_mesh_node(&s, box_mesh({0.3f, 0.3f, 0.3f}, glass), {1.0, 0.5, -3.5});
  const int glass_mesh = int(s.meshes.size()) - 1;
  copy(glass_mesh, {-1.0, 0.4, -3.0}, glm::angleAxis(0.5, glm::dvec3(0, 0, 1)), {1, 1, 1});
  Light sun;
  sun.type = Light::Type::kDirectional;
  sun.intensity = 2.0f;
  add_light_node(&s, sun, glm::dvec3(0.0), glm::angleAxis(-1.0, glm::dvec3(1, 0.3, 0)));
  Light bulb;
  bulb.intensity = 20.0f;
  add_light_node(&s, bulb, glm::dvec3(1.0, 2.0, -2.0));
  s.finalize();

  Tracer copied(s);
  TracerOptions instancing;
  instancing.max_copied_vertices = 0;
  Tracer instanced(s, instancing);
  // The box has 24 vertices: five copies (the hidden one too) and two glass boxes are copied by
  // default, and none with instancing (the floor's 4 vertices, on one node, are copied by both).
  EXPECT_EQ(copied.copied_vertices(), 4u + 5u * 24u + 2u * 24u);
  EXPECT_EQ(instanced.copied_vertices(), 4u);

  const Camera cam = Camera::look_at({0.0, 1.0, 1.0}, {0.0, -0.3, -5.0}, {0, 1, 0}, 0.9, 0.01);
  const int w = 64, h = 48;
  TraceStats st;
  int hits = 0, boxes = 0, differ = 0;
  for (int i = 0; i < w * h; ++i) {
    const Ray ray = cam.ray(i % w + 0.5, i / w + 0.5, w, h);
    const ShadedSample a = copied.trace(ray, &st);
    const ShadedSample b = instanced.trace(ray, &st);
    if (a.hit != b.hit || a.object_id != b.object_id ||
        glm::length(a.color - b.color) > 1e-3f * (1.0f + glm::length(a.color)) ||
        glm::length(a.position - b.position) > 1e-3f) {
      ++differ;
      continue;
    }
    hits += a.hit ? 1 : 0;
    boxes += a.hit && a.object_id != 0 ? 1 : 0;
  }
  EXPECT_GT(boxes, w * h / 20);  // the copies are in view
  EXPECT_GT(hits, w * h / 2);
  EXPECT_LE(differ, w * h / 100);
  EXPECT_EQ(st.sanitized, 0u);
}

TEST(TracerTest, TracingFromTwoThreadsGivesTheSameSamples) {
  const Scene s = busy_scene();
  Tracer tracer(s);
  tracer.set_time(1.3);
  const Camera cam = Camera::look_at({0.0, 1.0, 3.0}, {0.0, -0.5, -5.0}, {0, 1, 0}, 0.9, 0.01);
  const int w = 80, h = 60;
  std::vector<ShadedSample> serial(size_t(w * h)), a(size_t(w * h)), b(size_t(w * h));
  TraceStats st;
  for (int i = 0; i < w * h; ++i)
    serial[size_t(i)] = tracer.trace(cam.ray(i % w + 0.5, i / w + 0.5, w, h), &st);
  auto work = [&](std::vector<ShadedSample>* out, TraceStats* stats) {
    for (int i = 0; i < w * h; ++i)
      (*out)[size_t(i)] = tracer.trace(cam.ray(i % w + 0.5, i / w + 0.5, w, h), stats);
  };
  TraceStats sa, sb;
  std::thread ta(work, &a, &sa), tb(work, &b, &sb);
  ta.join();
  tb.join();
  for (size_t i = 0; i < serial.size(); ++i) {
    EXPECT_EQ(serial[i].color, a[i].color);
    EXPECT_EQ(serial[i].color, b[i].color);
    EXPECT_EQ(serial[i].position, b[i].position);
  }
  TraceStats sum = sa;
  sum += sb;
  EXPECT_EQ(sum.primary_rays, 2 * st.primary_rays);
  EXPECT_EQ(sum.shadow_rays, 2 * st.shadow_rays);
}

}  // namespace
}  // namespace afr
