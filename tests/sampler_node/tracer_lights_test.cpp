// Tests of the tracer's light picking (TracerOptions::light_samples; docs/sampler.md, "Many
// lights") against the tracer casting a shadow ray toward every light: equal where no light is
// blocked, equal on average where some are, the shadow rays it saves counted, and the crosshair's
// packets agreeing with single rays.
#include <afr/common/error.h>
#include <afr/sampler/tracer.h>

#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "tracer_test_scenes.h"

namespace afr::tracer_test {
namespace {

// A white Lambertian floor y = 0 ([-10, 10]^2) under `n` white point lights of unequal
// intensities on a ring of radius 3 at height 3, and a dark plate at height 1 over x in
// [-0.5, 0.5] that blocks some of them from the floor around the origin.
Scene many_lights_scene(int n, float range = 0.0f) {
  Scene s;
  s.ambient = glm::vec3(0.0f);
  const int floor = add_material(&s, glm::vec3(0.8f), 0.0f, 1.0f);
  const int dark = add_material(&s, glm::vec3(0.1f), 0.0f, 1.0f);
  s.materials[size_t(dark)].double_sided = true;
  add_mesh_node(&s, quad_mesh({-10, 0, 10}, {20, 0, 0}, {0, 0, -20}, floor));
  add_mesh_node(&s, quad_mesh({-0.5f, 1, 3}, {1, 0, 0}, {0, 0, -6}, dark));
  for (int i = 0; i < n; ++i) {
    Light light;
    light.intensity = 2.0f + float(i % 5);
    light.range = range;
    const double a = 2.0 * M_PI * (i + 0.5) / n;
    add_light_node(&s, light, glm::dvec3(3.0 * std::cos(a), 3.0, 3.0 * std::sin(a)));
  }
  s.finalize();
  return s;
}

Tracer tracer_with(const Scene& s, int light_samples) {
  TracerOptions o;
  o.light_samples = light_samples;
  return Tracer(s, o);
}

const glm::vec3 kEye(0.0f, 6.0f, 6.0f);

TEST(TracerLightsTest, PickedLightsAreExactWhereNoLightIsBlocked) {
  const Scene s = many_lights_scene(24);
  const Tracer every = tracer_with(s, 0);
  for (int k : {1, 2, 5}) {
    SCOPED_TRACE(k);
    const Tracer picking = tracer_with(s, k);
    TraceStats exact_stats, picked_stats;
    int points = 0;
    for (float x = 4.0f; x <= 8.0f; x += 0.5f) {
      for (float z = -4.0f; z <= 4.0f; z += 0.5f) {
        const Ray ray = ray_to(kEye, {x, 0.0f, z});
        const ShadedSample exact = every.trace(ray, &exact_stats);
        const ShadedSample picked = picking.trace(ray, &picked_stats);
        ASSERT_TRUE(exact.hit && picked.hit);
        // Lights of one color on a Lambertian floor: each pick, scaled, is the whole light.
        expect_near3(picked.color, exact.color, 2e-5f + 2e-5f * exact.color.g, "color");
        ++points;
      }
    }
    EXPECT_EQ(exact_stats.shadow_rays, uint64_t(24 * points));
    EXPECT_EQ(picked_stats.shadow_rays, uint64_t(k * points));
  }
}

// Around the origin the plate blocks some of the lights from each floor point: a pick's
// estimate is then more or less than the exact light, and over many points (each with its own
// number for the picks) the mean estimate is the mean exact light.
TEST(TracerLightsTest, PickedLightsAverageToTheExactLightWhereSomeAreBlocked) {
  const Scene s = many_lights_scene(24);
  const Tracer every = tracer_with(s, 0);
  for (int k : {1, 4}) {
    SCOPED_TRACE(k);
    const Tracer picking = tracer_with(s, k);
    TraceStats stats;
    double exact_sum = 0.0, picked_sum = 0.0, unblocked_sum = 0.0;
    int differing = 0, points = 0;
    const Tracer unshadowed = [&] {
      TracerOptions o;
      o.shadows = false;
      return Tracer(s, o);
    }();
    for (int j = 0; j < 80; ++j) {
      for (int i = 0; i < 80; ++i) {
        const glm::vec3 p(-1.5f + 3.0f * (i + 0.5f) / 80.0f, 0.0f,
                          -1.5f + 3.0f * (j + 0.5f) / 80.0f);
        const Ray ray = ray_to(kEye, p);
        const float exact = every.trace(ray, &stats).color.g;
        const float picked = picking.trace(ray, &stats).color.g;
        exact_sum += exact;
        picked_sum += picked;
        unblocked_sum += unshadowed.trace(ray, &stats).color.g;
        differing += std::abs(picked - exact) > 1e-3f * exact + 1e-5f;
        ++points;
      }
    }
    // The region is in part shadow, and picking differs from the exact light at most points.
    EXPECT_LT(exact_sum, 0.9 * unblocked_sum);
    EXPECT_GT(exact_sum, 0.2 * unblocked_sum);
    EXPECT_GT(differing, points / 4);
    // Standard error of the mean: at most (unblocked light) / (2 sqrt(points)), 0.6 % here.
    EXPECT_NEAR(picked_sum / exact_sum, 1.0, 0.03) << picked_sum << " vs " << exact_sum;
  }
}

// Where no more lights reach a point than it may pick (the others out of range), it casts one
// shadow ray toward each, as the tracer that does not pick.
TEST(TracerLightsTest, FewerReachingLightsThanPicksAreEachCastOnce) {
  const Scene s = many_lights_scene(24, 3.5f);
  const Tracer every = tracer_with(s, 0);
  const Tracer picking = tracer_with(s, 8);
  TraceStats exact_stats, picked_stats;
  for (float x : {-2.5f, 0.0f, 1.0f, 3.0f}) {
    const Ray ray = ray_to(kEye, {x, 0.0f, 2.8f});
    expect_near3(picking.trace(ray, &picked_stats).color, every.trace(ray, &exact_stats).color,
                 1e-6f, "color");
  }
  EXPECT_EQ(picked_stats.shadow_rays, exact_stats.shadow_rays);
  EXPECT_GT(exact_stats.shadow_rays, 0u);
  EXPECT_LT(exact_stats.shadow_rays, 4u * 8u);
}

// The crosshair's packets pick as trace() does: the picks depend on the surface point and the
// direction it is seen from, not on the query path.
TEST(TracerLightsTest, CrosshairWithPickedLightsEqualsFiveSingleRays) {
  const Scene s = many_lights_scene(12);
  const Tracer tracer = tracer_with(s, 3);
  const Camera cam = Camera::look_at({0.0, 6.0, 6.0}, {0.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, 0.9, 0.01);
  TraceStats stats;
  expect_crosshairs_equal_single_rays(tracer, cam, 48, 36, 2, &stats);
  EXPECT_GT(stats.shadow_rays, 0u);
}

TEST(TracerLightsTest, LightSamplesOutOfRangeAreRefusedByName) {
  const Scene s = many_lights_scene(2);
  for (int k : {-1, kMaxLightSamples + 1}) {
    try {
      tracer_with(s, k);
      ADD_FAILURE() << k << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("light samples"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace afr::tracer_test
