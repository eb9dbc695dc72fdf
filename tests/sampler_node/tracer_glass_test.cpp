// Tests of glass (KHR_materials_transmission, ior, volume, dispersion) and of shadow rays through
// glass and diffusely transmitting surfaces, on small scenes built here (tracer_test_scenes.h),
// against closed forms: Snell, Schlick, Beer-Lambert.
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
// Glass (KHR_materials_transmission, KHR_materials_ior)

int add_emitter(Scene* s, glm::vec3 emission) {
  const int m = add_material(s, glm::vec3(0.0f), 0.0f, 1.0f);
  s->materials[size_t(m)].emissive = emission;
  return m;
}

// Schlick's Fresnel reflectance of an interface between indices `ior` and `outer` (air: 1) at
// cosine c on the side of the lower index.
double schlick(double ior, double c, double outer = 1.0) {
  const double f0 = (ior - outer) * (ior - outer) / ((ior + outer) * (ior + outer));
  return f0 + (1.0 - f0) * std::pow(1.0 - c, 5.0);
}

// A tiny square emitter (0.01 wide) of the given radiance centred at (x, 0, z), facing +Z: where
// a test's closed form puts a ray.
void add_target(Scene* s, double x, double z, glm::vec3 radiance = glm::vec3(1.0f)) {
  const float w = 0.01f;
  add_mesh_node(s, quad_mesh({float(x) - w / 2, -w / 2, float(z)}, {w, 0, 0}, {0, w, 0},
                             add_emitter(s, radiance)));
}

// Makes glass `material` of s a volume (thickness 1) that keeps `color` per 2 units travelled.
void make_absorbing_volume(Scene* s, int material, glm::vec3 color) {
  Material& m = s->materials[size_t(material)];
  m.thickness = 1.0f;
  m.attenuation_color = color;
  m.attenuation_distance = 2.0f;
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
    add_target(&s, x_refracted, z_target, {1, 0, 0});
    add_target(&s, x_straight, z_target, {0, 1, 0});
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
    add_target(&s, x_refracted, z_target);
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
  make_absorbing_volume(&s, glass, glass_color);
  make_absorbing_volume(&s, liquid, water_color);
  add_mesh_node(&s, box_mesh({50.0f, 50.0f, top}, glass));
  add_mesh_node(&s, box_mesh({49.0f, 49.0f, float(water / 2)}, liquid));
  add_target(&s, x_target, z_target);
  s.finalize();
  TracerOptions o;
  o.max_mirror_depth = 4;  // four refractions
  Tracer tracer(s, o);
  TraceStats stats;
  const ShadedSample out = tracer.trace(Ray{origin, d}, &stats);
  const double f_air = schlick(n_glass, std::cos(theta));
  const double f_water = schlick(n_glass, std::cos(theta_water), n_water);
  const double fresnel = std::pow((1.0 - f_air) * (1.0 - f_water), 2.0);
  for (int c = 0; c < 3; ++c) {
    const double kept = std::pow(glass_color[c], 2 * wall / std::cos(theta_glass) / 2.0) *
                        std::pow(water_color[c], water / std::cos(theta_water) / 2.0);
    EXPECT_NEAR(out.color[c], fresnel * kept, 1e-4) << "channel " << c;
  }
  EXPECT_EQ(stats.sanitized, 0u);
}

// Two volumes whose surfaces coincide: a glass slab 1 thick on a water slab 1 thick, the glass's
// bottom face and the water's top face one plane, as a liquid modelled to fill its glass to the
// wall. A ray entering the glass's top at 40 degrees crosses into the water by the ratio of their
// iors (the glass-to-water Fresnel term), absorbs in each by its own color, leaves the water's
// bottom parallel to where it came from and lands where Snell's law at the three interfaces puts
// it, whichever slab the scene lists first (so whichever of the coincident faces Embree reports).
TEST(TracerTest, CoincidentVolumeSurfacesRefractAndAbsorbAsOneInterface) {
  const double n_glass = 1.5, n_water = 1.33;
  const double theta = 40.0 * M_PI / 180.0;
  const double theta_glass = std::asin(std::sin(theta) / n_glass);
  const double theta_water = std::asin(std::sin(theta) / n_water);
  const glm::vec3 d(float(std::sin(theta)), 0.0f, -float(std::cos(theta)));
  const glm::vec3 origin = glm::vec3(0.0f, 0.0f, 1.0f) - 2.0f * d;  // enters the top at x = 0
  const double z_target = -3.0;
  const double x_target =
      std::tan(theta_glass) + std::tan(theta_water) + (-1.0 - z_target) * std::tan(theta);
  const glm::vec3 glass_color(0.5f, 0.8f, 1.0f), water_color(1.0f, 0.6f, 0.3f);  // per 2 units
  for (const bool water_first : {false, true}) {
    SCOPED_TRACE(water_first ? "water listed first" : "glass listed first");
    Scene s;
    const int glass = add_glass(&s, float(n_glass));
    const int liquid = add_glass(&s, float(n_water));
    make_absorbing_volume(&s, glass, glass_color);
    make_absorbing_volume(&s, liquid, water_color);
    const auto glass_slab = [&] {
      add_mesh_node(&s, box_mesh({50.0f, 50.0f, 0.5f}, glass), glm::dvec3(0.0, 0.0, 0.5));
    };
    const auto water_slab = [&] {
      add_mesh_node(&s, box_mesh({49.0f, 49.0f, 0.5f}, liquid), glm::dvec3(0.0, 0.0, -0.5));
    };
    if (water_first) {
      water_slab();
      glass_slab();
    } else {
      glass_slab();
      water_slab();
    }
    add_target(&s, x_target, z_target);
    s.finalize();
    TracerOptions o;
    o.max_mirror_depth = 4;
    Tracer tracer(s, o);
    TraceStats stats;
    const ShadedSample out = tracer.trace(Ray{origin, d}, &stats);
    const double f_air = schlick(n_glass, std::cos(theta));
    const double f_water = schlick(n_glass, std::cos(theta_water), n_water);
    const double f_out = schlick(n_water, std::cos(theta));
    const double fresnel = (1.0 - f_air) * (1.0 - f_water) * (1.0 - f_out);
    for (int c = 0; c < 3; ++c) {
      const double kept = std::pow(glass_color[c], 1.0 / std::cos(theta_glass) / 2.0) *
                          std::pow(water_color[c], 1.0 / std::cos(theta_water) / 2.0);
      EXPECT_NEAR(out.color[c], fresnel * kept, 1e-4) << "channel " << c;
    }
    EXPECT_EQ(stats.sanitized, 0u);
  }
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
    add_target(&s, x_target, z_target);
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

}  // namespace
}  // namespace afr::tracer_test
