#include <afr/common/animation.h>

#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr {
namespace {

AnimationChannel translation_channel(Interpolation mode, std::vector<double> times,
                                     std::vector<glm::dvec4> values) {
  AnimationChannel ch;
  ch.node = 0;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = mode;
  ch.times = std::move(times);
  ch.values = std::move(values);
  ch.validate("test");
  return ch;
}

TEST(AnimationTest, StepHoldsEachKeyUntilTheNext) {
  auto ch = translation_channel(Interpolation::kStep, {1.0, 2.0, 4.0},
                                {{1, 0, 0, 0}, {2, 0, 0, 0}, {3, 0, 0, 0}});
  EXPECT_EQ(ch.evaluate(0.0).x, 1.0);  // before the first key
  EXPECT_EQ(ch.evaluate(1.0).x, 1.0);
  EXPECT_EQ(ch.evaluate(1.999).x, 1.0);
  EXPECT_EQ(ch.evaluate(2.0).x, 2.0);
  EXPECT_EQ(ch.evaluate(3.9).x, 2.0);
  EXPECT_EQ(ch.evaluate(4.0).x, 3.0);
  EXPECT_EQ(ch.evaluate(100.0).x, 3.0);  // after the last key
}

TEST(AnimationTest, LinearInterpolatesBetweenKeys) {
  auto ch =
      translation_channel(Interpolation::kLinear, {0.0, 2.0}, {{0, 10, -4, 0}, {4, 20, 4, 0}});
  const glm::dvec4 v = ch.evaluate(0.5);  // a quarter of the way
  EXPECT_DOUBLE_EQ(v.x, 1.0);
  EXPECT_DOUBLE_EQ(v.y, 12.5);
  EXPECT_DOUBLE_EQ(v.z, -2.0);
}

TEST(AnimationTest, LinearRotationIsSlerpAlongTheShortArc) {
  AnimationChannel ch;
  ch.path = AnimatedPath::kRotation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 1.0};
  // 0 and 90 degrees about +Z; the second key is stored negated (the same rotation).
  const double h = std::sqrt(0.5);
  ch.values = {{0, 0, 0, 1}, {0, 0, -h, -h}};
  ch.validate("test");
  const glm::dvec4 q = ch.evaluate(0.5);
  // Halfway is 45 degrees about +Z: (0, 0, sin 22.5, cos 22.5) up to sign.
  const double s = std::sin(M_PI / 8.0), c = std::cos(M_PI / 8.0);
  const double sign = q.w < 0 ? -1.0 : 1.0;
  EXPECT_NEAR(sign * q.z, s, 1e-12);
  EXPECT_NEAR(sign * q.w, c, 1e-12);
  EXPECT_NEAR(q.x, 0.0, 1e-12);
  EXPECT_NEAR(q.y, 0.0, 1e-12);
}

TEST(AnimationTest, CubicSplineIsHermiteWithTangentsScaledByTheInterval) {
  // Keys at t = 1 and t = 3 (interval 2 s): value 0 -> 1, out-tangent 0.5/s, in-tangent -1/s.
  auto ch = translation_channel(Interpolation::kCubicSpline, {1.0, 3.0},
                                {{9, 9, 9, 0},
                                 {0, 0, 0, 0},
                                 {0.5, 0, 0, 0},  // key 0
                                 {-1, 0, 0, 0},
                                 {1, 0, 0, 0},
                                 {7, 7, 7, 0}});  // key 1
  // By hand at s = 0.25 (t = 1.5): h00 = 0.84375, h10 = 0.140625, h01 = 0.15625,
  // h11 = -0.046875; m0 = 2 * 0.5 = 1, m1 = 2 * -1 = -2.
  const double expected = 0.84375 * 0 + 0.140625 * 1 + 0.15625 * 1 + -0.046875 * -2;
  EXPECT_NEAR(ch.evaluate(1.5).x, expected, 1e-12);
  EXPECT_DOUBLE_EQ(ch.evaluate(1.0).x, 0.0);  // keys are hit exactly
  EXPECT_DOUBLE_EQ(ch.evaluate(3.0).x, 1.0);
  EXPECT_DOUBLE_EQ(ch.evaluate(-5.0).x, 0.0);  // clamped, tangents never leak out
  EXPECT_DOUBLE_EQ(ch.evaluate(50.0).x, 1.0);
}

TEST(AnimationTest, CubicSplineAgreesWithNumericalDerivativeAtKeys) {
  auto ch = translation_channel(Interpolation::kCubicSpline, {0.0, 0.5, 2.0},
                                {{0, 0, 0, 0},
                                 {1, 0, 0, 0},
                                 {3, 0, 0, 0},
                                 {-2, 0, 0, 0},
                                 {2, 0, 0, 0},
                                 {0.25, 0, 0, 0},
                                 {4, 0, 0, 0},
                                 {-1, 0, 0, 0},
                                 {0, 0, 0, 0}});
  const double d = 1e-6;
  // The out-tangent of key 0 and the in-tangent of key 1 are slopes per second.
  EXPECT_NEAR((ch.evaluate(d).x - ch.evaluate(0.0).x) / d, 3.0, 1e-4);
  EXPECT_NEAR((ch.evaluate(0.5).x - ch.evaluate(0.5 - d).x) / d, -2.0, 1e-4);
  EXPECT_NEAR((ch.evaluate(0.5 + d).x - ch.evaluate(0.5).x) / d, 0.25, 1e-4);
}

TEST(AnimationTest, ValidateRejectsBadChannels) {
  AnimationChannel ch;
  ch.interpolation = Interpolation::kLinear;
  EXPECT_THROW(ch.validate("empty"), Error);
  ch.times = {0.0, 0.0};
  ch.values = {{0, 0, 0, 0}, {1, 0, 0, 0}};
  EXPECT_THROW(ch.validate("equal times"), Error);
  ch.times = {0.0, NAN};
  EXPECT_THROW(ch.validate("nan time"), Error);
  ch.times = {0.0, 1.0};
  ch.interpolation = Interpolation::kCubicSpline;
  try {
    ch.validate("channel 7");
    FAIL() << "a cubic channel with one value per key must be rejected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("channel 7"), std::string::npos);
  }
}

// Keys out of order or at repeated times are sorted (stable) and, of keys at one time, the last
// kept, their values (three each for CUBICSPLINE) and weights moving with them; ordered
// channels and channels validate must refuse (a NaN time, a wrong value count) are left alone.
TEST(AnimationTest, RepairKeyOrderSortsKeysAndKeepsTheLastOfEqualTimes) {
  AnimationChannel ch;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 2.0, 1.0, 1.0, 3.0};
  ch.values = {{0, 0, 0, 0}, {2, 0, 0, 0}, {10, 0, 0, 0}, {11, 0, 0, 0}, {3, 0, 0, 0}};
  const AnimationChannel::KeyRepair fix = ch.repair_key_order();
  EXPECT_TRUE(fix.repaired);
  EXPECT_EQ(fix.dropped, 1u);
  EXPECT_EQ(ch.times, (std::vector<double>{0.0, 1.0, 2.0, 3.0}));
  ASSERT_EQ(ch.values.size(), 4u);
  EXPECT_EQ(ch.values[1].x, 11.0);  // the later of the two keys at t = 1
  EXPECT_EQ(ch.values[2].x, 2.0);
  EXPECT_NO_THROW(ch.validate("repaired"));
  EXPECT_DOUBLE_EQ(ch.evaluate(1.5).x, 6.5);

  // Ordered: nothing to do.
  EXPECT_FALSE(ch.repair_key_order().repaired);

  // CUBICSPLINE: in-tangent, value and out-tangent travel together.
  AnimationChannel cubic;
  cubic.interpolation = Interpolation::kCubicSpline;
  cubic.times = {1.0, 0.0};
  cubic.values = {{-1, 0, 0, 0}, {1, 0, 0, 0}, {-2, 0, 0, 0},
                  {-3, 0, 0, 0}, {3, 0, 0, 0}, {-4, 0, 0, 0}};
  EXPECT_TRUE(cubic.repair_key_order().repaired);
  EXPECT_EQ(cubic.times, (std::vector<double>{0.0, 1.0}));
  ASSERT_EQ(cubic.values.size(), 6u);
  EXPECT_EQ(cubic.values[0].x, -3.0);
  EXPECT_EQ(cubic.values[1].x, 3.0);
  EXPECT_EQ(cubic.values[3].x, -1.0);
  EXPECT_EQ(cubic.values[5].x, -2.0);

  // Weights: weight_count numbers per key.
  AnimationChannel w;
  w.path = AnimatedPath::kWeights;
  w.interpolation = Interpolation::kStep;
  w.weight_count = 2;
  w.times = {0.5, 0.5, 0.0};
  w.weights = {1, 2, 3, 4, 5, 6};
  const AnimationChannel::KeyRepair wfix = w.repair_key_order();
  EXPECT_TRUE(wfix.repaired);
  EXPECT_EQ(wfix.dropped, 1u);
  EXPECT_EQ(w.times, (std::vector<double>{0.0, 0.5}));
  EXPECT_EQ(w.weights, (std::vector<double>{5, 6, 3, 4}));

  // What validate refuses stays for it to name.
  AnimationChannel bad;
  bad.times = {1.0, NAN, 0.0};
  bad.values = {{0, 0, 0, 0}, {1, 0, 0, 0}, {2, 0, 0, 0}};
  EXPECT_FALSE(bad.repair_key_order().repaired);
  EXPECT_THROW(bad.validate("nan"), Error);
  bad.times = {1.0, 0.0};
  EXPECT_FALSE(bad.repair_key_order().repaired);  // 3 values for 2 keys
  EXPECT_THROW(bad.validate("count"), Error);
}

// A weights channel interpolates each of its weights on its own, as a scalar channel would:
// the reference is a translation channel per weight.
TEST(AnimationTest, WeightsChannelsInterpolateEveryWeightLikeAScalarChannel) {
  const std::vector<double> times = {0.0, 0.5, 2.0};
  const std::vector<std::vector<double>> per_weight = {
      {0.0, 1.0, 3.0, -2.0, 2.0, 0.25, 4.0, -1.0, 0.0},
      {1.0, 0.5, 0.0, 2.0, -1.0, 0.5, 0.0, 1.0, 3.0}};
  for (Interpolation mode :
       {Interpolation::kStep, Interpolation::kLinear, Interpolation::kCubicSpline}) {
    const size_t values = mode == Interpolation::kCubicSpline ? 9 : 3;
    AnimationChannel weights;
    weights.path = AnimatedPath::kWeights;
    weights.interpolation = mode;
    weights.times = times;
    weights.weight_count = 2;
    for (size_t v = 0; v < values; ++v) {
      for (const std::vector<double>& w : per_weight) weights.weights.push_back(w[v]);
    }
    weights.validate("weights");
    std::vector<AnimationChannel> scalars;
    for (const std::vector<double>& w : per_weight) {
      std::vector<glm::dvec4> v;
      for (size_t k = 0; k < values; ++k) v.push_back({w[k], 0, 0, 0});
      scalars.push_back(translation_channel(mode, times, v));
    }
    for (double t : {-1.0, 0.0, 0.2, 0.5, 0.7, 1.9, 2.0, 5.0}) {
      float out[2];
      weights.evaluate_weights(t, out);
      for (size_t i = 0; i < 2; ++i) {
        EXPECT_NEAR(out[i], scalars[i].evaluate(t).x, 1e-6)
            << to_string(mode) << " t = " << t << " weight " << i;
      }
    }
  }
}

TEST(AnimationTest, ValidateRejectsBadWeightsChannels) {
  AnimationChannel ch;
  ch.path = AnimatedPath::kWeights;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 1.0};
  ch.weight_count = 2;
  ch.weights = {0, 0, 1, 1};
  ch.validate("good");
  ch.weights = {0, 0, 1};
  EXPECT_THROW(ch.validate("one weight short"), Error);
  ch.weights = {0, 0, 1, NAN};
  EXPECT_THROW(ch.validate("nan weight"), Error);
  ch.weights = {0, 0, 1, 1};
  ch.weight_count = 0;
  EXPECT_THROW(ch.validate("no weights"), Error);
  ch.weight_count = 2;
  ch.values = {{0, 0, 0, 0}, {0, 0, 0, 0}};
  EXPECT_THROW(ch.validate("vector values"), Error);
  AnimationChannel translation;
  translation.times = {0.0};
  translation.values = {{0, 0, 0, 0}};
  translation.weights = {1.0};
  EXPECT_THROW(translation.validate("translation with weights"), Error);
}

}  // namespace
}  // namespace afr
