#include <afr/common/animation.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <array>
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
    case AnimatedPath::kWeights:
      return "weights";
  }
  return "?";
}

std::string_view to_string(AnimatedProperty property) {
  switch (property) {
    case AnimatedProperty::kLightColor:
      return "light color";
    case AnimatedProperty::kLightIntensity:
      return "light intensity";
    case AnimatedProperty::kLightRange:
      return "light range";
    case AnimatedProperty::kLightInnerCone:
      return "spot inner cone angle";
    case AnimatedProperty::kLightOuterCone:
      return "spot outer cone angle";
    case AnimatedProperty::kCameraYfov:
      return "camera yfov";
    case AnimatedProperty::kCameraZnear:
      return "camera znear";
    case AnimatedProperty::kCameraYmag:
      return "camera ymag";
    case AnimatedProperty::kBaseColorFactor:
      return "base color factor";
    case AnimatedProperty::kMetallicFactor:
      return "metallic factor";
    case AnimatedProperty::kRoughnessFactor:
      return "roughness factor";
    case AnimatedProperty::kEmissiveFactor:
      return "emissive factor";
    case AnimatedProperty::kEmissiveStrength:
      return "emissive strength";
    case AnimatedProperty::kAlphaCutoff:
      return "alpha cutoff";
    case AnimatedProperty::kNormalScale:
      return "normal texture scale";
    case AnimatedProperty::kOcclusionStrength:
      return "occlusion strength";
    case AnimatedProperty::kClearcoatFactor:
      return "clearcoat factor";
    case AnimatedProperty::kClearcoatRoughnessFactor:
      return "clearcoat roughness factor";
    case AnimatedProperty::kSheenColorFactor:
      return "sheen color factor";
    case AnimatedProperty::kSheenRoughnessFactor:
      return "sheen roughness factor";
    case AnimatedProperty::kSpecularFactor:
      return "specular factor";
    case AnimatedProperty::kSpecularColorFactor:
      return "specular color factor";
    case AnimatedProperty::kIridescenceFactor:
      return "iridescence factor";
    case AnimatedProperty::kIridescenceIor:
      return "iridescence ior";
    case AnimatedProperty::kIridescenceThicknessMinimum:
      return "iridescence thickness minimum";
    case AnimatedProperty::kIridescenceThicknessMaximum:
      return "iridescence thickness maximum";
    case AnimatedProperty::kAnisotropyStrength:
      return "anisotropy strength";
    case AnimatedProperty::kAnisotropyRotation:
      return "anisotropy rotation";
    case AnimatedProperty::kTransmissionFactor:
      return "transmission factor";
    case AnimatedProperty::kIor:
      return "ior";
    case AnimatedProperty::kThicknessFactor:
      return "thickness factor";
    case AnimatedProperty::kAttenuationDistance:
      return "attenuation distance";
    case AnimatedProperty::kAttenuationColor:
      return "attenuation color";
    case AnimatedProperty::kDispersion:
      return "dispersion";
    case AnimatedProperty::kDiffuseTransmissionFactor:
      return "diffuse transmission factor";
    case AnimatedProperty::kDiffuseTransmissionColor:
      return "diffuse transmission color";
    case AnimatedProperty::kUvOffset:
      return "texture transform offset";
    case AnimatedProperty::kUvRotation:
      return "texture transform rotation";
    case AnimatedProperty::kUvScale:
      return "texture transform scale";
    case AnimatedProperty::kNodeVisible:
      return "node visibility";
  }
  return "?";
}

int component_count(AnimatedProperty property) {
  switch (property) {
    case AnimatedProperty::kLightColor:
    case AnimatedProperty::kEmissiveFactor:
    case AnimatedProperty::kSheenColorFactor:
    case AnimatedProperty::kSpecularColorFactor:
    case AnimatedProperty::kAttenuationColor:
    case AnimatedProperty::kDiffuseTransmissionColor:
      return 3;
    case AnimatedProperty::kBaseColorFactor:
      return 4;
    case AnimatedProperty::kUvOffset:
    case AnimatedProperty::kUvScale:
      return 2;
    default:
      return 1;
  }
}

bool is_light_property(AnimatedProperty property) {
  return property <= AnimatedProperty::kLightOuterCone;
}

bool is_node_property(AnimatedProperty property) {
  return property == AnimatedProperty::kNodeVisible;
}

bool is_uv_property(AnimatedProperty property) {
  return property == AnimatedProperty::kUvOffset || property == AnimatedProperty::kUvRotation ||
         property == AnimatedProperty::kUvScale;
}

bool is_camera_property(AnimatedProperty property) {
  return property == AnimatedProperty::kCameraYfov || property == AnimatedProperty::kCameraZnear ||
         property == AnimatedProperty::kCameraYmag;
}

AnimationChannel::KeyRepair AnimationChannel::repair_key_order() {
  KeyRepair result;
  const size_t n = times.size();
  const size_t per_key = interpolation == Interpolation::kCubicSpline ? 3 : 1;
  bool ordered = true;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(times[i])) return result;
    if (i > 0 && !(times[i] > times[i - 1])) ordered = false;
  }
  const bool weighted = path == AnimatedPath::kWeights;
  const size_t values_per_key = weighted ? per_key * weight_count : per_key;
  const size_t stored = weighted ? weights.size() : values.size();
  if (ordered || values_per_key == 0 || stored != n * values_per_key) return result;

  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return times[a] < times[b]; });
  std::vector<size_t> kept;
  for (size_t k : order) {
    if (!kept.empty() && times[kept.back()] == times[k]) {
      kept.back() = k;  // the later in the file
    } else {
      kept.push_back(k);
    }
  }
  std::vector<double> new_times;
  std::vector<glm::dvec4> new_values;
  std::vector<double> new_weights;
  for (size_t k : kept) {
    new_times.push_back(times[k]);
    for (size_t j = 0; j < values_per_key; ++j) {
      if (weighted) {
        new_weights.push_back(weights[k * values_per_key + j]);
      } else {
        new_values.push_back(values[k * values_per_key + j]);
      }
    }
  }
  result.repaired = true;
  result.dropped = n - kept.size();
  times = std::move(new_times);
  if (weighted) {
    weights = std::move(new_weights);
  } else {
    values = std::move(new_values);
  }
  return result;
}

void AnimationChannel::validate(std::string_view what) const {
  if (times.empty()) throw Error(fmt::format("{}: animation channel has no keyframes", what));
  const size_t per_key = interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (path == AnimatedPath::kWeights) {
    if (weight_count == 0) {
      throw Error(fmt::format("{}: weights channel animates no morph weights", what));
    }
    if (!values.empty()) {
      throw Error(fmt::format("{}: weights channel has {} vector values (its values are weights)",
                              what, values.size()));
    }
    if (weights.size() != times.size() * per_key * weight_count) {
      throw Error(fmt::format(
          "{}: {} weights channel has {} keyframes of {} weights but {} values (expected {})", what,
          to_string(interpolation), times.size(), weight_count, weights.size(),
          times.size() * per_key * weight_count));
    }
    for (size_t i = 0; i < weights.size(); ++i) {
      if (!std::isfinite(weights[i])) {
        throw Error(fmt::format("{}: morph weight {} of keyframe value {} is not finite", what,
                                i % weight_count, i / weight_count));
      }
    }
  } else {
    if (!weights.empty() || weight_count != 0) {
      throw Error(fmt::format("{}: {} channel has morph weights", what, to_string(path)));
    }
    if (values.size() != times.size() * per_key) {
      throw Error(fmt::format("{}: {} {} channel has {} keyframes but {} values (expected {})",
                              what, to_string(interpolation), to_string(path), times.size(),
                              values.size(), times.size() * per_key));
    }
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

// Where time t falls among the keys: on key k (`hold`: before the first key, at or after the
// last, or a single key), or between keys k and k + 1 at fraction s of their interval td.
struct KeySpan {
  size_t k = 0;
  double s = 0.0;
  double td = 0.0;
  bool hold = true;
};

KeySpan locate(const std::vector<double>& times, double t) {
  const size_t n = times.size();
  KeySpan span;
  if (n == 1 || !(t > times.front())) return span;  // also catches NaN t
  if (t >= times.back()) {
    span.k = n - 1;
    return span;
  }
  // The last key at or before t: times[k] <= t < times[k + 1].
  span.k = size_t(std::upper_bound(times.begin(), times.end(), t) - times.begin()) - 1;
  span.td = times[span.k + 1] - times[span.k];
  span.s = (t - times[span.k]) / span.td;
  span.hold = false;
  return span;
}

// The Hermite basis of glTF's cubic spline at s: weights of p0, m0, p1, m1.
std::array<double, 4> hermite(double s) {
  const double s2 = s * s;
  const double s3 = s2 * s;
  return {2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2};
}

}  // namespace

glm::dvec4 AnimationChannel::evaluate(double t) const {
  const bool cubic = interpolation == Interpolation::kCubicSpline;
  auto key_value = [&](size_t k) { return cubic ? values[3 * k + 1] : values[k]; };
  const bool rotation = path == AnimatedPath::kRotation;
  auto finish = [&](const glm::dvec4& v) { return rotation ? normalized_quat(v) : v; };

  const KeySpan span = locate(times, t);
  const size_t k = span.k;
  if (span.hold) return finish(key_value(k));
  switch (interpolation) {
    case Interpolation::kStep:
      return finish(values[k]);
    case Interpolation::kLinear:
      if (rotation) return normalized_quat(slerp_xyzw(values[k], values[k + 1], span.s));
      return glm::mix(values[k], values[k + 1], span.s);
    case Interpolation::kCubicSpline: {
      // Hermite spline with per-second tangents scaled by the key interval.
      const std::array<double, 4> h = hermite(span.s);
      return finish(h[0] * values[3 * k + 1] + h[1] * (span.td * values[3 * k + 2]) +
                    h[2] * values[3 * (k + 1) + 1] + h[3] * (span.td * values[3 * (k + 1)]));
    }
  }
  return finish(key_value(0));
}

void AnimationChannel::evaluate_weights(double t, float* out) const {
  const size_t n = weight_count;
  const bool cubic = interpolation == Interpolation::kCubicSpline;
  // The weights of value v (key k's value is v = k, or 3 k + 1 for CUBICSPLINE).
  auto value = [&](size_t v) { return &weights[v * n]; };
  const KeySpan span = locate(times, t);
  const size_t k = span.k;
  if (span.hold || interpolation == Interpolation::kStep) {
    const double* w = value(cubic ? 3 * k + 1 : k);
    for (size_t i = 0; i < n; ++i) out[i] = float(w[i]);
    return;
  }
  if (interpolation == Interpolation::kLinear) {
    const double* a = value(k);
    const double* b = value(k + 1);
    for (size_t i = 0; i < n; ++i) out[i] = float(a[i] + span.s * (b[i] - a[i]));
    return;
  }
  const std::array<double, 4> h = hermite(span.s);
  const double* p0 = value(3 * k + 1);
  const double* m0 = value(3 * k + 2);
  const double* p1 = value(3 * (k + 1) + 1);
  const double* m1 = value(3 * (k + 1));
  for (size_t i = 0; i < n; ++i) {
    out[i] =
        float(h[0] * p0[i] + h[1] * (span.td * m0[i]) + h[2] * p1[i] + h[3] * (span.td * m1[i]));
  }
}

}  // namespace afr
