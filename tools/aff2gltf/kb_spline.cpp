#include "kb_spline.h"

#include <afr/common/check.h>

#include <algorithm>
#include <cmath>

namespace afr::aff {
namespace {

constexpr double kEpsilon = 1e-3;  // the reference's threshold in log, exp and slerp

// 2h / span, the KB correction for uneven key spacing. The span is zero only for a segment of
// zero length, which is never evaluated.
double spacing_factor(double h, double span) { return span > 0.0 ? 2.0 * h / span : 0.0; }

// The weights of section 4.1 for segment i: D_o = alpha (P_i - P_{i-1}) + beta (P_{i+1} - P_i),
// D_i = gamma (P_{i+1} - P_i) + delta (P_{i+2} - P_{i+1}).
struct KbWeights {
  double alpha, beta, gamma, delta;
};

template <typename Key>
KbWeights kb_weights(const std::vector<Key>& keys, size_t i) {
  const Key& k0 = keys[i - 1];
  const Key& k1 = keys[i];
  const Key& k2 = keys[i + 1];
  const Key& k3 = keys[i + 2];
  const double h = k2.t - k1.t;
  const double g_o = spacing_factor(h, k2.t - k0.t);
  const double g_i = spacing_factor(h, k3.t - k1.t);
  KbWeights w;
  w.alpha = 0.5 * g_o * (1.0 - k1.tension) * (1.0 + k1.continuity) * (1.0 + k1.bias);
  w.beta = 0.5 * g_o * (1.0 - k1.tension) * (1.0 - k1.continuity) * (1.0 - k1.bias);
  w.gamma = 0.5 * g_i * (1.0 - k2.tension) * (1.0 - k2.continuity) * (1.0 + k2.bias);
  w.delta = 0.5 * g_i * (1.0 - k2.tension) * (1.0 + k2.continuity) * (1.0 - k2.bias);
  return w;
}

template <typename Key>
std::vector<double> times_of(const std::vector<Key>& keys) {
  std::vector<double> times(keys.size());
  for (size_t k = 0; k < keys.size(); ++k) times[k] = keys[k].t;
  return times;
}

glm::dvec3 vec(const glm::dquat& q) { return glm::dvec3(q.x, q.y, q.z); }

}  // namespace

SegmentPosition locate_segment(const std::vector<double>& times, double t) {
  const size_t n = times.size();
  AFR_CHECK(n >= 4);
  if (t <= times[1]) return {1, 0.0};
  if (t >= times[n - 2]) return {n - 3, 1.0};
  // First j in 2..n-2 with t < t_j; the segment is j - 1.
  const auto it = std::upper_bound(times.begin() + 2, times.begin() + (n - 1), t);
  const size_t i = size_t(it - times.begin()) - 1;
  return {i, (t - times[i]) / (times[i + 1] - times[i])};
}

// ---- TcbSpline ------------------------------------------------------------------------------

TcbSpline::TcbSpline(std::vector<TcbKey> keys) : keys_(std::move(keys)), times_(times_of(keys_)) {
  AFR_CHECK(keys_.size() >= 4);
}

TcbSpline::Tangents TcbSpline::segment_tangents(size_t i) const {
  AFR_CHECK(i >= 1 && i + 2 < keys_.size());
  const KbWeights w = kb_weights(keys_, i);
  const glm::dvec3 delta = keys_[i + 1].value - keys_[i].value;
  Tangents d;
  d.out_of_start = w.alpha * (keys_[i].value - keys_[i - 1].value) + w.beta * delta;
  d.into_end = w.gamma * delta + w.delta * (keys_[i + 2].value - keys_[i + 1].value);
  return d;
}

glm::dvec3 TcbSpline::evaluate(double t) const {
  const SegmentPosition s = locate_segment(times_, t);
  const glm::dvec3& p0 = keys_[s.segment].value;
  const glm::dvec3& p1 = keys_[s.segment + 1].value;
  if (s.u == 0.0) return p0;
  if (s.u == 1.0) return p1;
  const Tangents d = segment_tangents(s.segment);
  const glm::dvec3 delta = p1 - p0;
  const double u = s.u;
  // P(u) = P_i + D_o u + (3 delta - 2 D_o - D_i) u^2 + (-2 delta + D_o + D_i) u^3
  const glm::dvec3 c2 = 3.0 * delta - 2.0 * d.out_of_start - d.into_end;
  const glm::dvec3 c3 = -2.0 * delta + d.out_of_start + d.into_end;
  return p0 + u * (d.out_of_start + u * (c2 + u * c3));
}

// ---- Quaternion helpers ---------------------------------------------------------------------

namespace quat {

glm::dvec3 log(const glm::dquat& q) {
  const glm::dvec3 v = vec(q);
  if (std::abs(q.w) < 1.0) {
    const double phi = std::acos(q.w);
    const double s = std::sin(phi);
    if (std::abs(s) >= kEpsilon) return v * (phi / s);
  }
  return v;
}

glm::dquat exp(const glm::dvec3& v) {
  const double phi = glm::length(v);
  const double s = std::sin(phi);
  const glm::dvec3 u = std::abs(s) >= kEpsilon ? v * (s / phi) : v;
  return glm::dquat(std::cos(phi), u.x, u.y, u.z);
}

glm::dquat slerp(const glm::dquat& p, const glm::dquat& q, double s) {
  const double c = std::clamp(glm::dot(p, q), -1.0, 1.0);
  const double phi = std::acos(c);
  const double sin_phi = std::sin(phi);
  if (sin_phi < kEpsilon) return p;
  const double a = std::sin((1.0 - s) * phi) / sin_phi;
  const double b = std::sin(s * phi) / sin_phi;
  return glm::dquat(a * p.w + b * q.w, a * p.x + b * q.x, a * p.y + b * q.y, a * p.z + b * q.z);
}

glm::dquat squad(const glm::dquat& p, const glm::dquat& a, const glm::dquat& b, const glm::dquat& q,
                 double s) {
  return slerp(slerp(p, q, s), slerp(a, b, s), 2.0 * s * (1.0 - s));
}

}  // namespace quat

// ---- RotationSpline -------------------------------------------------------------------------

RotationSpline::RotationSpline(std::vector<RotationKey> keys)
    : keys_(std::move(keys)), times_(times_of(keys_)) {
  const size_t n = keys_.size();
  AFR_CHECK(n >= 4);
  q_.resize(n);
  for (size_t k = 0; k < n; ++k) {
    const double len = glm::length(keys_[k].axis);
    const glm::dvec3 axis = len > 0.0 ? keys_[k].axis / len : glm::dvec3(1.0, 0.0, 0.0);
    const double half = 0.5 * keys_[k].angle;
    const glm::dvec3 v = std::sin(half) * axis;
    q_[k] = glm::dquat(std::cos(half), v.x, v.y, v.z);
  }
  // Section 4.2, hemisphere alignment: Q_0 = q_0, Q_1 = q_1, Q_k flipped against Q_{k-1} for
  // k = 2..n-2, and the last (phantom) key kept as written.
  aligned_ = q_;
  for (size_t k = 2; k + 1 < n; ++k) {
    if (glm::dot(aligned_[k - 1], q_[k]) < 0.0) aligned_[k] = -q_[k];
  }
}

glm::dquat RotationSpline::evaluate(double t) const {
  // Section 4.2: squad between Q_i and Q_{i+1} with KB inner control points A, B.
  const SegmentPosition s = locate_segment(times_, t);
  const size_t i = s.segment;
  const glm::dquat& p = aligned_[i];
  const glm::dquat& q = aligned_[i + 1];
  if (s.u == 0.0) return glm::normalize(p);
  if (s.u == 1.0) return glm::normalize(q);
  const KbWeights w = kb_weights(keys_, i);
  const glm::dvec3 L = quat::log(glm::conjugate(p) * q);
  const glm::dvec3 L_prev = quat::log(glm::conjugate(aligned_[i - 1]) * p);
  // The reference takes the fourth key before alignment (q_{i+2}, not Q_{i+2}).
  const glm::dvec3 L_next = quat::log(glm::conjugate(q) * q_[i + 2]);
  const glm::dvec3 D_o = w.alpha * L_prev + w.beta * L;
  const glm::dvec3 D_i = w.gamma * L + w.delta * L_next;
  const glm::dquat A = p * quat::exp(0.5 * (D_o - L));
  const glm::dquat B = q * quat::exp(0.5 * (L - D_i));
  return glm::normalize(quat::squad(p, A, B, q, s.u));
}

}  // namespace afr::aff
