// Kochanek-Bartels keyframe splines of BART AFF `k` blocks, evaluated exactly as the reference
// implementation does (docs: shared/reference/aff-format.md, section 4): Hermite segments for
// `transl` and `scale`, a quaternion KB spline evaluated with squad for `rot`. All in double.
#pragma once

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <cstddef>
#include <vector>

namespace afr::aff {

// One `transl` or `scale` row: time, value, tension, continuity, bias.
struct TcbKey {
  double t = 0.0;
  glm::dvec3 value{0.0};
  double tension = 0.0;
  double continuity = 0.0;
  double bias = 0.0;
};

// One `rot` row; the angle is in radians (AFF writes degrees).
struct RotationKey {
  double t = 0.0;
  glm::dvec3 axis{0.0, 1.0, 0.0};
  double angle = 0.0;
  double tension = 0.0;
  double continuity = 0.0;
  double bias = 0.0;
};

// Where time t falls in a channel of n >= 4 keys: `segment` i in 1..n-3 runs from key i to key
// i+1 and u = (t - t_i) / (t_{i+1} - t_i). Keys 0 and n-1 are phantom keys that only shape
// tangents: up to t_1 the channel holds key 1 (reported as segment 1, u = 0), from t_{n-2} on it
// holds key n-2 (segment n-3, u = 1).
struct SegmentPosition {
  size_t segment = 1;
  double u = 0.0;
};
// Section 4.1: inside the key range, the first i with t < t_{i+1}, so a zero-length segment
// (two keys at one time) is never returned. `times` must hold n >= 4 non-decreasing values.
SegmentPosition locate_segment(const std::vector<double>& times, double t);

// Section 4.1: a `transl`/`scale` channel.
class TcbSpline {
 public:
  // Requires at least 4 keys in non-decreasing time (the parser checks this).
  explicit TcbSpline(std::vector<TcbKey> keys);

  glm::dvec3 evaluate(double t) const;

  // The Hermite end derivatives of segment i (1 <= i <= n-3), per unit of u: D_o leaves key i,
  // D_i arrives at key i+1. Only meaningful for segments of non-zero length.
  struct Tangents {
    glm::dvec3 out_of_start{0.0};
    glm::dvec3 into_end{0.0};
  };
  Tangents segment_tangents(size_t i) const;

  const std::vector<TcbKey>& keys() const { return keys_; }
  const std::vector<double>& times() const { return times_; }

 private:
  std::vector<TcbKey> keys_;
  std::vector<double> times_;
};

// Section 4.2: a `rot` channel, a quaternion KB spline evaluated with squad.
class RotationSpline {
 public:
  // Requires at least 4 keys in non-decreasing time. Key axes are normalised (a zero axis is
  // taken as +X, as the reference's angle/axis round trip does).
  explicit RotationSpline(std::vector<RotationKey> keys);

  // A unit quaternion (glm order w, x, y, z).
  glm::dquat evaluate(double t) const;

  const std::vector<RotationKey>& keys() const { return keys_; }
  const std::vector<double>& times() const { return times_; }

 private:
  std::vector<RotationKey> keys_;
  std::vector<double> times_;
  std::vector<glm::dquat> q_;        // key rotations as written
  std::vector<glm::dquat> aligned_;  // Q_k: hemisphere-aligned in sequence
};

// The squad helpers of section 4.2, with the reference's thresholds (epsilon = 1e-3).
namespace quat {
glm::dvec3 log(const glm::dquat& q);  // vector part of the pure quaternion log
glm::dquat exp(const glm::dvec3& v);  // exp of the pure quaternion (0; v)
glm::dquat slerp(const glm::dquat& p, const glm::dquat& q, double s);  // no shortest-path flip
glm::dquat squad(const glm::dquat& p, const glm::dquat& a, const glm::dquat& b, const glm::dquat& q,
                 double s);
}  // namespace quat

}  // namespace afr::aff
