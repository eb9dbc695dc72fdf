// glTF 2.0 animation samplers: keyframe times and values for one animated property of one
// node, evaluated at a time in seconds with STEP, LINEAR (slerp for rotations) or CUBICSPLINE
// (Hermite) interpolation, exactly as the glTF 2.0 specification, Appendix C, defines them.
#pragma once

#include <afr/common/math.h>

#include <string_view>
#include <vector>

namespace afr {

enum class Interpolation { kStep, kLinear, kCubicSpline };
enum class AnimatedPath { kTranslation, kRotation, kScale };

std::string_view to_string(Interpolation interpolation);
std::string_view to_string(AnimatedPath path);

// One channel: drives `path` of node `node`. Values are vec3 (translation, scale) stored in
// xyz, or quaternions stored as (x, y, z, w) like glTF. For CUBICSPLINE there are three values
// per key in glTF order: in-tangent, value, out-tangent (tangents per second).
struct AnimationChannel {
  int node = -1;
  AnimatedPath path = AnimatedPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<double> times;  // strictly increasing, seconds
  std::vector<glm::dvec4> values;

  // Throws afr::Error if times are not strictly increasing and finite, the value count does
  // not match the interpolation, or the channel is empty. `what` names the channel in the
  // message.
  void validate(std::string_view what) const;

  // Value at time t (seconds). Before the first key: the first value; after the last: the last
  // value. Rotations come back normalised.
  glm::dvec4 evaluate(double t) const;

  double start_time() const { return times.front(); }
  double end_time() const { return times.back(); }
};

}  // namespace afr
