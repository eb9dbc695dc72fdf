#include <afr/common/animation.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace afr {

std::string_view to_string(Interpolation interpolation) {
  switch (interpolation) {
    case Interpolation::kStep:
      return "STEP";
    case Interpolation::kLinear:
      return "LINEAR";
    case Interpolation::kCubicSpline:
      return "CUBICSPLINE";
  }
  return "?";
}

std::string_view to_string(AnimatedPath path) {
  switch (path) {
    case AnimatedPath::kTranslation:
      return "translation";
    case AnimatedPath::kRotation:
      return "rotation";
    case AnimatedPath::kScale:
      return "scale";
  }
  return "?";
}

void AnimationChannel::validate(std::string_view what) const {
  if (times.empty()) throw Error(fmt::format("{}: animation channel has no keyframes", what));
  const size_t per_key = interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (values.size() != times.size() * per_key) {
    throw Error(fmt::format("{}: {} {} channel has {} keyframes but {} values (expected {})", what,
                            to_string(interpolation), to_string(path), times.size(), values.size(),
                            times.size() * per_key));
  }
  for (size_t i = 0; i < times.size(); ++i) {
    if (!std::isfinite(times[i])) {
      throw Error(fmt::format("{}: keyframe time {} is not finite", what, i));
    }
    if (i > 0 && !(times[i] > times[i - 1])) {
      throw Error(fmt::format("{}: keyframe times are not strictly increasing at key {} ({} <= {})",
                              what, i, times[i], times[i - 1]));
    }
  }
  for (size_t i = 0; i < values.size(); ++i) {
    const glm::dvec4& v = values[i];
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(v.w)) {
      throw Error(fmt::format("{}: keyframe value {} is not finite", what, i));
    }
  }
}

namespace {

glm::dvec4 normalized_quat(const glm::dvec4& q) {
  const double len = glm::length(q);
  return len > 0.0 ? q / len : glm::dvec4(0.0, 0.0, 0.0, 1.0);
}

// glTF 2.0 Appendix C: spherical linear interpolation along the shorter arc.
glm::dvec4 slerp_xyzw(glm::dvec4 a, glm::dvec4 b, double s) {
  double d = glm::dot(a, b);
  if (d < 0.0) {
    b = -b;
    d = -d;
  }
  if (d > 0.9995) return normalized_quat(glm::mix(a, b, s));
  const double angle = std::acos(std::min(d, 1.0));
  const double sin_angle = std::sin(angle);
  return (std::sin((1.0 - s) * angle) * a + std::sin(s * angle) * b) / sin_angle;
}

}  // namespace

glm::dvec4 AnimationChannel::evaluate(double t) const {
  const bool cubic = interpolation == Interpolation::kCubicSpline;
  const size_t n = times.size();
  auto key_value = [&](size_t k) { return cubic ? values[3 * k + 1] : values[k]; };
  const bool rotation = path == AnimatedPath::kRotation;
  auto finish = [&](const glm::dvec4& v) { return rotation ? normalized_quat(v) : v; };

  if (n == 1 || !(t > times.front())) return finish(key_value(0));  // also catches NaN t
  if (t >= times.back()) return finish(key_value(n - 1));

  // The last key at or before t: times[k] <= t < times[k + 1].
  const size_t k = size_t(std::upper_bound(times.begin(), times.end(), t) - times.begin()) - 1;
  const double td = times[k + 1] - times[k];
  const double s = (t - times[k]) / td;

  switch (interpolation) {
    case Interpolation::kStep:
      return finish(values[k]);
    case Interpolation::kLinear:
      if (rotation) return normalized_quat(slerp_xyzw(values[k], values[k + 1], s));
      return glm::mix(values[k], values[k + 1], s);
    case Interpolation::kCubicSpline: {
      // Hermite spline with per-second tangents scaled by the key interval.
      const glm::dvec4 p0 = values[3 * k + 1];
      const glm::dvec4 m0 = td * values[3 * k + 2];
      const glm::dvec4 p1 = values[3 * (k + 1) + 1];
      const glm::dvec4 m1 = td * values[3 * (k + 1)];
      const double s2 = s * s;
      const double s3 = s2 * s;
      return finish((2.0 * s3 - 3.0 * s2 + 1.0) * p0 + (s3 - 2.0 * s2 + s) * m0 +
                    (-2.0 * s3 + 3.0 * s2) * p1 + (s3 - s2) * m1);
    }
  }
  return finish(key_value(0));
}

}  // namespace afr
