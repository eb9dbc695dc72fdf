// The phi-accrual failure detector (failure_detector.h): suspicion from the intervals
// actually seen, with a floor and a ceiling.
#include <afr/common/error.h>
#include <afr/common/failure_detector.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr {
namespace {

// Heartbeats every `interval` s from t = 0 until `until`; returns the last arrival.
double beat(FailureDetector* d, double interval, double until) {
  double t = 0.0;
  d->reset(t);
  while (t + interval <= until) {
    t += interval;
    d->heard(t);
  }
  return t;
}

TEST(FailureDetectorTest, PhiIsTheNormalTailOfTheSilence) {
  FailureDetectorOptions o;
  o.min_deviation = 0.0;
  FailureDetector d(1.0, o);  // first guess: intervals 0.75 and 1.25: mean 1, deviation 0.25
  d.reset(10.0);
  EXPECT_NEAR(d.mean(), 1.0, 1e-12);
  EXPECT_NEAR(d.deviation(), 0.25, 1e-12);
  // At the mean, half of all intervals are longer: phi = -log10(0.5).
  EXPECT_NEAR(d.phi(11.0), -std::log10(0.5), 1e-9);
  // Two deviations beyond: P = 0.02275.
  EXPECT_NEAR(d.phi(11.5), -std::log10(0.0227501319), 1e-6);
  EXPECT_GT(d.phi(12.0), d.phi(11.5));
}

TEST(FailureDetectorTest, SteadyHeartbeatsAreSuspectedJustAfterTheFloor) {
  // 0.2 s heartbeats with no spread: the deviation's minimum (0.1 s) and phi 8 (z = 5.61)
  // give 0.2 + 0.561 s, above the 0.75 s floor.
  FailureDetector d(0.2);
  const double last = beat(&d, 0.2, 10.0);
  EXPECT_NEAR(d.suspect_after(), 0.2 + 0.561, 0.01);
  EXPECT_FALSE(d.suspect(last + 0.6));  // a node stopped for 0.4 s between two heartbeats
  EXPECT_TRUE(d.suspect(last + 0.8));   // a dead one, noticed within a second
}

TEST(FailureDetectorTest, TheFloorHoldsWhateverTheHistory) {
  FailureDetectorOptions o;
  o.min_deviation = 0.0;
  o.floor = 0.75;
  FailureDetector d(0.01, o);
  const double last = beat(&d, 0.01, 2.0);
  EXPECT_LT(d.mean() + 6.0 * d.deviation(), 0.1);
  EXPECT_FALSE(d.suspect(last + 0.7));
  EXPECT_TRUE(d.suspect(last + 0.76));
}

TEST(FailureDetectorTest, IrregularArrivalsWidenTheTolerance) {
  // A loaded machine: heartbeats 0.2 s apart, every fifth one a second late. Intervals 0.2,
  // 0.2, 0.2, 0.2, 1.0: mean 0.36 s, deviation 0.32 s, suspected after 0.36 + 5.61 x 0.32 s.
  FailureDetectorOptions o;
  o.window = 60;
  FailureDetector busy(0.2, o), idle(0.2, o);
  double t = 0.0;
  busy.reset(t);
  for (int i = 0; i < 60; ++i) busy.heard(t += i % 5 == 4 ? 1.0 : 0.2);
  beat(&idle, 0.2, 13.0);
  EXPECT_NEAR(busy.mean(), 0.36, 0.01);
  EXPECT_NEAR(busy.deviation(), 0.32, 0.01);
  EXPECT_NEAR(busy.suspect_after(), 0.36 + 5.61 * 0.32, 0.05);
  EXPECT_FALSE(busy.suspect(t + 1.5));  // a pause like those seen is no proof of death
  EXPECT_TRUE(idle.suspect(13.0 + 1.5));
}

TEST(FailureDetectorTest, TheCeilingBoundsAnyHistory) {
  FailureDetectorOptions o;
  o.ceiling = 5.0;
  FailureDetector d(30.0, o);  // a peer that claims to speak twice a minute
  const double last = beat(&d, 30.0, 300.0);
  EXPECT_DOUBLE_EQ(d.suspect_after(), 5.0);
  EXPECT_FALSE(d.suspect(last + 4.9));
  EXPECT_TRUE(d.suspect(last + 5.1));
}

TEST(FailureDetectorTest, OldIntervalsLeaveTheWindow) {
  // A burst of long gaps ages out: 64 steady intervals later the detector is strict again.
  FailureDetectorOptions o;
  o.window = 64;
  FailureDetector d(0.2, o);
  double t = 0.0;
  d.reset(t);
  for (int i = 0; i < 10; ++i) d.heard(t += 2.0);
  EXPECT_GT(d.suspect_after(), 4.0);
  for (int i = 0; i < 64; ++i) d.heard(t += 0.2);
  EXPECT_EQ(d.intervals(), 64u);
  EXPECT_NEAR(d.suspect_after(), 0.761, 0.01);
}

TEST(FailureDetectorTest, ArrivalsOutOfOrderOrAtOnceDoNotBreakIt) {
  FailureDetector d(0.2);
  d.reset(5.0);
  d.heard(5.0);
  d.heard(4.0);  // an earlier time (two threads' clocks): counts as an interval of 0
  EXPECT_DOUBLE_EQ(d.last_heard(), 5.0);
  EXPECT_TRUE(std::isfinite(d.suspect_after()));
  EXPECT_FALSE(d.suspect(5.7));
  EXPECT_TRUE(std::isinf(d.phi(1e6)));  // a silence beyond any tail: suspicion without bound
}

TEST(FailureDetectorTest, BadOptionsAreNamed) {
  FailureDetectorOptions o;
  o.floor = 2.0;
  o.ceiling = 1.0;
  EXPECT_THROW(FailureDetector(0.2, o), Error);
  EXPECT_THROW(FailureDetector(0.0), Error);
  EXPECT_THROW(FailureDetector(std::nan("")), Error);
  FailureDetectorOptions w;
  w.window = 1;
  EXPECT_THROW(FailureDetector(0.2, w), Error);
}

}  // namespace
}  // namespace afr
