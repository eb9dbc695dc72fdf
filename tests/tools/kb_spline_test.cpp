#include "kb_spline.h"

#include "aff_parser.h"
#include "test_paths.h"

#include "support/numbers.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>

namespace afr::aff {
namespace {

using afr::testing::kDeg;

TcbKey key(double t, glm::dvec3 v, double bias = 0.0) {
  TcbKey k;
  k.t = t;
  k.value = v;
  k.bias = bias;
  return k;
}

RotationKey rot_key(double t, glm::dvec3 axis, double degrees) {
  RotationKey k;
  k.t = t;
  k.axis = axis;
  k.angle = degrees * kDeg;
  return k;
}

// Catmull-Rom through p1..p2 with neighbours p0, p3 (uniform keys): the KB spline with
// T = C = B = 0, written in its textbook matrix form.
double catmull_rom(double p0, double p1, double p2, double p3, double u) {
  return 0.5 * (2 * p1 + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u * u +
                (-p0 + 3 * p1 - 3 * p2 + p3) * u * u * u);
}

// ---- TcbSpline ------------------------------------------------------------------------------

// aff-format.md section 7: keys 1-4 of `k toycar` `transl` (keys 0 and 5 do not enter
// segment 2; any values do).
TEST(TcbSplineTest, WorkedExampleToyCarAtSixSeconds) {
  const TcbSpline s({key(-1.0, {9, 9, 9}), key(3.0, {4.45, 0, 2.75}),
                     key(5.0, {3.75, 0, 2.75}, 0.75), key(7.1, {3.30, 0, 2.00}),
                     key(7.3, {3.20, 0, 0.45}), key(9.8, {-9, -9, -9})});
  const glm::dvec3 p = s.evaluate(6.0);
  EXPECT_NEAR(p.x, 3.511199, 1e-6);
  EXPECT_EQ(p.y, 0.0);
  EXPECT_NEAR(p.z, 2.638651, 1e-6);
}

TEST(TcbSplineTest, UniformKeysWithZeroTcbAreCatmullRom) {
  const double v[] = {0.0, 1.0, 3.0, 2.0, -1.0, 0.5};
  std::vector<TcbKey> keys;
  for (int k = 0; k < 6; ++k) keys.push_back(key(10.0 + 0.5 * k, {v[k], 2 * v[k], 0}));
  const TcbSpline s(keys);
  for (int i = 1; i <= 3; ++i) {
    for (double u = 0.0; u < 1.0; u += 0.125) {
      const double expected = catmull_rom(v[i - 1], v[i], v[i + 1], v[i + 2], u);
      const glm::dvec3 p = s.evaluate(10.0 + 0.5 * (i + u));
      EXPECT_NEAR(p.x, expected, 1e-12) << "segment " << i << " u " << u;
      EXPECT_NEAR(p.y, 2 * expected, 1e-12);
    }
  }
}

TEST(TcbSplineTest, PassesThroughKeysAndClampsToTheInnerKeys) {
  const TcbSpline s({key(0, {5, 5, 5}), key(1, {1, 0, 0}), key(2.5, {2, 1, 0}, 0.3),
                     key(3, {0, 4, 1}), key(7, {-1, 0, 2}), key(8, {7, 7, 7})});
  EXPECT_EQ(s.evaluate(1.0), glm::dvec3(1, 0, 0));
  EXPECT_EQ(s.evaluate(2.5), glm::dvec3(2, 1, 0));
  EXPECT_EQ(s.evaluate(3.0), glm::dvec3(0, 4, 1));
  EXPECT_EQ(s.evaluate(7.0), glm::dvec3(-1, 0, 2));
  // Keys 0 and n-1 are phantoms: never reached.
  EXPECT_EQ(s.evaluate(-100.0), glm::dvec3(1, 0, 0));
  EXPECT_EQ(s.evaluate(0.5), glm::dvec3(1, 0, 0));
  EXPECT_EQ(s.evaluate(7.5), glm::dvec3(-1, 0, 2));
  EXPECT_EQ(s.evaluate(100.0), glm::dvec3(-1, 0, 2));
}

// With T = C = B = 0 the spacing correction makes the velocity (per second) continuous at keys,
// however unevenly they are spaced.
TEST(TcbSplineTest, VelocityIsContinuousAtUnevenlySpacedKeys) {
  const TcbSpline s({key(0, {0, 0, 0}), key(1, {1, 2, 0}), key(1.3, {2, 1, 1}), key(4, {0, 0, 3}),
                     key(4.2, {1, 1, 1}), key(9, {0, 0, 0})});
  for (const double t : {1.3, 4.0}) {
    // Second-order one-sided differences from each side.
    const double h = 1e-5;
    const glm::dvec3 left =
        (3.0 * s.evaluate(t) - 4.0 * s.evaluate(t - h) + s.evaluate(t - 2 * h)) / (2 * h);
    const glm::dvec3 right =
        (-3.0 * s.evaluate(t) + 4.0 * s.evaluate(t + h) - s.evaluate(t + 2 * h)) / (2 * h);
    EXPECT_LT(glm::length(left - right), 1e-5) << "at " << t;
  }
}

// Two keys at one time: the segment between them is never evaluated; at that time the second
// key holds, just before it the curve arrives at the first.
TEST(TcbSplineTest, RepeatedKeyTimeJumpsToTheSecondKey) {
  const TcbSpline s({key(0, {0, 0, 0}), key(1, {1, 0, 0}), key(2, {2, 0, 0}), key(2, {5, 0, 0}),
                     key(3, {6, 0, 0}), key(4, {7, 0, 0})});
  EXPECT_EQ(s.evaluate(2.0), glm::dvec3(5, 0, 0));
  EXPECT_NEAR(s.evaluate(2.0 - 1e-9).x, 2.0, 1e-6);
  EXPECT_TRUE(std::isfinite(s.evaluate(2.5).x));
}

// ---- RotationSpline -------------------------------------------------------------------------

// About one fixed axis, squad with KB control points is the KB (here Catmull-Rom) spline of
// the angle: the squad of section 4.2 reduces to the Hermite cubic of the half angles.
TEST(RotationSplineTest, FixedAxisRotationFollowsCatmullRomOfTheAngle) {
  const double angles[] = {0.0, 20.0, 50.0, 60.0, 100.0, 130.0};
  const glm::dvec3 axis = glm::normalize(glm::dvec3(1, 2, -2));
  std::vector<RotationKey> keys;
  for (int k = 0; k < 6; ++k) keys.push_back(rot_key(k, axis, angles[k]));
  const RotationSpline s(keys);
  for (int i = 1; i <= 3; ++i) {
    for (double u = 0.0; u < 1.0; u += 0.1) {
      const double expected =
          catmull_rom(angles[i - 1], angles[i], angles[i + 1], angles[i + 2], u) * kDeg;
      const glm::dquat q = s.evaluate(i + u);
      const glm::dquat r = glm::angleAxis(expected, axis);
      EXPECT_NEAR(std::abs(glm::dot(q, r)), 1.0, 1e-12) << "segment " << i << " u " << u;
    }
  }
}

TEST(RotationSplineTest, ExactAtKeysUnitEverywhereAndClamped) {
  const RotationSpline s({rot_key(0, {0, 1, 0}, 0), rot_key(1, {0, 1, 0}, 30),
                          rot_key(2, {1, 0, 0}, 45), rot_key(3, {0, 0, 2}, 170),
                          rot_key(4, {0, 1, 1}, -60), rot_key(5, {0, 1, 0}, 0)});
  EXPECT_NEAR(std::abs(glm::dot(s.evaluate(2.0), glm::angleAxis(45 * kDeg, glm::dvec3(1, 0, 0)))),
              1.0, 1e-12);
  EXPECT_NEAR(std::abs(glm::dot(s.evaluate(3.0), glm::angleAxis(170 * kDeg, glm::dvec3(0, 0, 1)))),
              1.0, 1e-12);
  EXPECT_NEAR(std::abs(glm::dot(s.evaluate(-5.0), glm::angleAxis(30 * kDeg, glm::dvec3(0, 1, 0)))),
              1.0, 1e-12);
  const glm::dquat last = glm::angleAxis(-60 * kDeg, glm::normalize(glm::dvec3(0, 1, 1)));
  EXPECT_NEAR(std::abs(glm::dot(s.evaluate(50.0), last)), 1.0, 1e-12);
  for (double t = 1.0; t <= 4.0; t += 0.01) EXPECT_NEAR(glm::length(s.evaluate(t)), 1.0, 1e-12);
}

// ---- The reference values of aff-format.md section 7, on the kitchen's keyframes -----------

const Scene* kitchen() {
  static const std::unique_ptr<Scene> scene = [] {
    const auto path = test::kitchen_aff();
    return path.empty() ? nullptr : std::make_unique<Scene>(parse_aff_file(path));
  }();
  return scene.get();
}

#define REQUIRE_KITCHEN()                                                    \
  if (!kitchen()) GTEST_SKIP() << "BART kitchen not found (AFR_SHARED_DIR)"; \
  const Scene& scene = *kitchen()

void expect_vec3_near(const glm::dvec3& a, const glm::dvec3& b, double tolerance) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

TEST(KitchenKeyframesTest, ToyCarTranslationMatchesTheReference) {
  REQUIRE_KITCHEN();
  const TcbSpline s(scene.keyframes.at("toycar").translation);
  expect_vec3_near(s.evaluate(6.0), {3.511199, 0.0, 2.638651}, 1e-6);
  expect_vec3_near(s.evaluate(4.0), {4.152388, 0.0, 2.761433}, 1e-6);
  expect_vec3_near(s.evaluate(10.0), {2.678804, 0.0, 0.603692}, 1e-6);
  expect_vec3_near(s.evaluate(3.0), {4.45, 0.0, 2.75}, 1e-12);
  expect_vec3_near(s.evaluate(0.0), {4.45, 0.0, 2.75}, 1e-12);
  expect_vec3_near(s.evaluate(20.0), {2.75, 0.0, 3.40}, 1e-12);
  expect_vec3_near(s.evaluate(25.0), {2.75, 0.0, 3.40}, 1e-12);
}

TEST(KitchenKeyframesTest, ToyCarRotationMatchesTheReference) {
  REQUIRE_KITCHEN();
  const RotationSpline s(scene.keyframes.at("toycar").rotation);
  const glm::dquat at_key = s.evaluate(6.0);
  EXPECT_NEAR(std::abs(glm::dot(at_key, glm::angleAxis(125.883545 * kDeg, glm::dvec3(0, 1, 0)))),
              1.0, 1e-12);
  glm::dquat q = s.evaluate(6.1);
  if (q.w < 0) q = -q;
  EXPECT_NEAR(q.w, 0.492486, 1e-6);
  EXPECT_NEAR(q.y, 0.870320, 1e-6);
  EXPECT_NEAR(q.x, 0.0, 1e-12);
  EXPECT_NEAR(q.z, 0.0, 1e-12);
  EXPECT_NEAR(2.0 * std::acos(q.w) / kDeg, 120.99180, 1e-4);
}

TEST(KitchenKeyframesTest, ToyCarScaleMatchesTheReference) {
  REQUIRE_KITCHEN();
  const TcbSpline s(scene.keyframes.at("toycar").scale);
  expect_vec3_near(s.evaluate(19.78), {0.755220, 1.0, 1.0}, 1e-6);
  expect_vec3_near(s.evaluate(20.5), {0.5, 1.0, 1.0}, 1e-12);  // the 0.1 key is a phantom
}

TEST(KitchenKeyframesTest, CameraAtSixSecondsMatchesTheReference) {
  REQUIRE_KITCHEN();
  const Keyframes& k = scene.keyframes.at("camera");
  const glm::dvec3 eye = TcbSpline(k.translation).evaluate(6.0);
  const glm::dquat r = RotationSpline(k.rotation).evaluate(6.0);
  expect_vec3_near(eye, {3.45734, 0.14686, 0.30611}, 1e-5);
  expect_vec3_near(r * glm::dvec3(0, 0, -1), {0.11773, 0.00114, 0.99305}, 1e-5);
  expect_vec3_near(r * glm::dvec3(0, 1, 0), {0.01519, 0.99988, -0.00295}, 1e-5);
}

}  // namespace
}  // namespace afr::aff
