#include <afr/common/failure_detector.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace afr {

namespace {

// -log10 of the standard normal's upper tail at z.
double phi_of_z(double z) {
  const double tail = 0.5 * std::erfc(z / std::sqrt(2.0));
  return tail > 0.0 ? -std::log10(tail) : INFINITY;
}

}  // namespace

FailureDetector::FailureDetector(double expected_interval, FailureDetectorOptions options)
    : options_(options) {
  if (!(expected_interval > 0.0) || !std::isfinite(expected_interval)) {
    throw Error(
        fmt::format("failure detector: expected interval {} s must be > 0", expected_interval));
  }
  if (!(options_.floor > 0.0 && options_.ceiling >= options_.floor &&
        std::isfinite(options_.ceiling) && options_.threshold > 0.0 &&
        options_.min_deviation >= 0.0 && options_.window >= 2)) {
    throw Error(fmt::format(
        "failure detector: floor {} s, ceiling {} s, threshold {}, min deviation {} s, window {}:"
        " need 0 < floor <= ceiling, threshold > 0, deviation >= 0, window >= 2",
        options_.floor, options_.ceiling, options_.threshold, options_.min_deviation,
        options_.window));
  }
  // phi grows with z: bisect for the threshold's z once.
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (phi_of_z(mid) < options_.threshold ? lo : hi) = mid;
  }
  z_ = hi;
  intervals_.reserve(options_.window);
  // The first guess: the expected interval with a quarter of it as spread, until real
  // intervals take over the window.
  add(0.75 * expected_interval);
  add(1.25 * expected_interval);
}

void FailureDetector::reset(double now) { last_ = now; }

void FailureDetector::heard(double now) {
  add(std::max(0.0, now - last_));
  last_ = std::max(last_, now);
}

void FailureDetector::add(double interval) {
  if (intervals_.size() < options_.window) {
    intervals_.push_back(interval);
  } else {
    intervals_[next_] = interval;
    next_ = (next_ + 1) % options_.window;
  }
  // Summed afresh (at most `window` terms): no drift from adding and removing.
  sum_ = sum_sq_ = 0.0;
  for (double v : intervals_) {
    sum_ += v;
    sum_sq_ += v * v;
  }
}

double FailureDetector::deviation() const {
  const double n = double(intervals_.size());
  const double m = sum_ / n;
  return std::max(options_.min_deviation, std::sqrt(std::max(0.0, sum_sq_ / n - m * m)));
}

double FailureDetector::phi(double now) const {
  return phi_of_z((silence(now) - mean()) / deviation());
}

double FailureDetector::suspect_after() const {
  return std::clamp(mean() + z_ * deviation(), options_.floor, options_.ceiling);
}

}  // namespace afr
