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

#include "tracer_test_scenes.h"

namespace afr::tracer_test {
namespace {

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

  // Within range, KHR_lights_punctual's window 1 - (d / range)^4 dims the light.
  Light within;
  within.range = 6.0f;
  ShadowScene c{within};
  const glm::vec3 ambient = lambert_reference(c, p, false, true);
  const float window = 1.0f - std::pow(std::sqrt(20.0f) / 6.0f, 4.0f);
  expect_near3(Tracer(c.s).trace(ray_to(eye, p), &stats).color,
               ambient + window * (lambert_reference(c, p, true, true) - ambient), 1e-5f,
               "within range");
}

// A light far away with a range beyond it (a sun in a scene of planetary scale): its window
// is computed without overflowing a float, where d^4 and range^4 would.
TEST(TracerTest, TheRangeWindowOfAFarLightStaysFinite) {
  Scene s;
  s.ambient = glm::vec3(0.0f);
  const int floor = add_material(&s, glm::vec3(0.5f), 0.0f, 1.0f);
  add_mesh_node(&s, quad_mesh({-5, 0, 5}, {10, 0, 0}, {0, 0, -10}, floor));
  Light sun;
  sun.intensity = 2.5e19f;  // 1 lux at 5e9
  sun.range = 1e10f;
  add_light_node(&s, sun, glm::dvec3(0.0, 5e9, 0.0), glm::dquat(1.0, 0.0, 0.0, 0.0));
  s.finalize();
  TraceStats stats;
  const ShadedSample hit = Tracer(s).trace(ray_to({0.0f, 1.0f, 3.0f}, {0.0f, 0.0f, 0.0f}), &stats);
  ASSERT_TRUE(hit.hit);
  // Lambert 0.5 / pi, irradiance 1 at the window's 1 - 0.5^4.
  expect_near3(hit.color, glm::vec3(0.5f / std::numbers::pi_v<float> * 0.9375f), 1e-4f,
               "far light");
  EXPECT_EQ(stats.sanitized, 0u);
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

// A scene with every kind of geometry a tracer builds: static (a floor), rigidly moving (a box),
// morphing (a square whose morph weight lifts it) and filtered whose filters read animated
// materials (a masked square whose alpha cutoff rises past its opacity, a pane whose
// transmission rises so that it lets the light's shadow rays through).
Scene scene_of_every_geometry() {
  Scene s;
  s.ambient = glm::vec3(0.1f);
  s.background = glm::vec3(0.3f, 0.4f, 0.5f);
  const int grey = add_material(&s, glm::vec3(0.5f), 0.0f, 0.5f);
  add_mesh_node(&s, quad_mesh({-10, -1, 10}, {20, 0, 0}, {0, 0, -20}, grey));
  add_moving_box(&s, grey);
  const int masked = add_material(&s, {1, 0, 0}, 0.0f, 1.0f);
  s.materials[size_t(masked)].alpha_mode = Material::AlphaMode::kMask;
  s.materials[size_t(masked)].base_color_factor.a = 0.5f;
  add_mesh_node(&s, quad_mesh({-3, -1, -3}, {1.5f, 0, 0}, {0, 2, 0}, masked));
  const int pane = add_material(&s, {0.2f, 0.9f, 0.2f}, 0.0f, 0.0f);
  add_mesh_node(&s, quad_mesh({0.5f, 2, -1}, {2, 0, 0}, {0, 0, -2}, pane));  // under the light
  Mesh morphing = quad_mesh({-3, -0.5f, 0}, {1.5f, 0, 0}, {0, 0, -1.5f}, grey);
  MorphTarget lift;
  lift.positions.assign(morphing.primitives[0].positions.size(), glm::vec3(0, 1, 0));
  morphing.primitives[0].targets = {lift};
  morphing.weights = {0.0f};
  const int morph = add_mesh_node(&s, morphing);
  AnimationChannel weight;
  weight.node = morph;
  weight.path = AnimatedPath::kWeights;
  weight.times = {0.0, 2.0};
  weight.weights = {0.0, 1.0};
  weight.weight_count = 1;
  s.channels.push_back(weight);
  auto rising = [](AnimatedProperty property, int index, double from, double to) {
    PropertyChannel c;
    c.property = property;
    c.index = index;
    c.curve.times = {0.0, 2.0};
    c.curve.values = {{from, 0, 0, 0}, {to, 0, 0, 0}};
    return c;
  };
  s.property_channels = {rising(AnimatedProperty::kAlphaCutoff, masked, 0.25, 0.75),
                         rising(AnimatedProperty::kTransmissionFactor, pane, 0.0, 1.0)};
  add_light_node(&s, Light{}, glm::dvec3(1.5, 4.0, -2.0));
  s.finalize();
  return s;
}

// A tracer that shares another's geometry (Tracer::ShareGeometry: a sampler pool's threads)
// traces as a tracer built alone does at its own time, while the one it shares with is at
// another: camera rays, crosshairs (packets) and occlusion rays over the scene above, at 0.3 s
// and 1.7 s, where the cut-away square, the pane's shadow, the lifted square and the box differ;
// and it goes on doing so after the tracer it shared with, the scene's holder, is gone.
TEST(TracerTest, ATracerSharingGeometryTracesAsOneBuiltAloneAtItsOwnTime) {
  const Scene s = scene_of_every_geometry();
  // The first tracer holds a scene of its own (no copy), which goes with the last tracer.
  auto first = std::make_unique<Tracer>(std::make_shared<const Scene>(s));
  Tracer second(*first, Tracer::ShareGeometry{});
  EXPECT_EQ(second.copied_vertices(), first->copied_vertices());
  first->set_time(0.3);
  second.set_time(1.7);
  Tracer alone_early(s), alone_late(s);
  alone_early.set_time(0.3);
  alone_late.set_time(1.7);

  const glm::vec3 eye(0.0f, 3.0f, 6.0f);
  std::vector<Ray> rays;
  for (int j = 0; j < 24; ++j) {
    for (int i = 0; i < 24; ++i) {
      rays.push_back(ray_to(eye, {-6.0f + 0.5f * float(i), -1.0f, 2.0f - 0.5f * float(j)}));
    }
  }
  rays.push_back(ray_to(eye, {-2.25f, 0.0f, -3.0f}));  // the masked square, kept and then cut
  TraceStats stats;
  int differing = 0;  // rays whose color differs between the two times
  auto expect_same_everywhere = [&](const Tracer& shared, const Tracer& alone, const char* what) {
    SCOPED_TRACE(what);
    for (const Ray& r : rays)
      expect_same_sample(shared.trace(r, &stats), alone.trace(r, &stats), 1e-5f);
    const Camera& camera = alone.camera();
    for (double y = 4.5; y < 64.0; y += 9.0) {
      for (double x = 4.5; x < 64.0; x += 9.0) {
        std::array<ShadedSample, 5> a, b;
        shared.trace_crosshair(camera, x, y, 64, 64, &a, &stats);
        alone.trace_crosshair(camera, x, y, 64, 64, &b, &stats);
        for (size_t k = 0; k < 5; ++k) expect_same_sample(a[k], b[k], 1e-5f);
      }
    }
    for (const Ray& r : rays) {
      const glm::vec3 to = r.origin + 12.0f * r.direction;
      EXPECT_EQ(shared.occluded(r.origin, to, &stats), alone.occluded(r.origin, to, &stats));
    }
  };
  expect_same_everywhere(*first, alone_early, "the first tracer at 0.3 s");
  expect_same_everywhere(second, alone_late, "the sharing tracer at 1.7 s");
  for (const Ray& r : rays) {
    const glm::vec3 a = alone_early.trace(r, &stats).color, b = alone_late.trace(r, &stats).color;
    differing += glm::length(a - b) > 0.02f;
  }
  EXPECT_GT(differing, 20) << "the two times must differ for the comparison to mean anything";
  const ShadedSample kept = alone_early.trace(rays.back(), &stats);
  const ShadedSample cut = alone_late.trace(rays.back(), &stats);
  EXPECT_GT(kept.color.r, 2.0f * kept.color.g);  // the red square
  EXPECT_LT(cut.color.r, 2.0f * cut.color.g);    // cut away: the grey floor behind

  first.reset();
  second.set_time(0.9);
  Tracer alone(s);
  alone.set_time(0.9);
  expect_same_everywhere(second, alone, "the sharing tracer alone at 0.9 s");
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
  // Radiance that overflowed is as bright as a sample can be, not black; the other channels
  // keep what they had.
  EXPECT_EQ(r.color.r, 65504.0f);
  EXPECT_LT(r.color.g, 1.0f);

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
// Crosshairs and threads

TEST(TracerTest, CrosshairEqualsFiveSingleRays) {
  const Scene s = busy_scene();
  for (bool packet : {true, false}) {
    TracerOptions o;
    o.packet_crosshair = packet;
    Tracer tracer(s, o);
    tracer.set_time(0.7);
    const Camera cam =
        Camera::look_at({0.0, 1.0, 3.0}, {0.0, -0.5, -5.0}, {0.0, 1.0, 0.0}, 0.9, 0.01);
    TraceStats stats;
    expect_crosshairs_equal_single_rays(tracer, cam, 64, 48, 3, &stats);
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
}  // namespace afr::tracer_test
