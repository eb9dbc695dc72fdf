// A fast exp for the reconstruction filter's Gaussians: the CPU backend evaluates several per
// sample, and std::exp would take most of a frame. Accurate to about 2e-7 relative, which is
// far below the 1/255 steps of a display and below the differences of GPU exp implementations.
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace afr {

// e^u for u in [-ln 2 / 2, ln 2 / 2] by its Taylor series to degree 6 (remainder
// (ln 2 / 2)^7 / 7! < 1.3e-7): for a float, or lane by lane with the same operations for a
// GCC/Clang vector of floats.
template <typename T>
inline T exp_series(T u) {
  T p = T{} + 1.0f / 720.0f;
  p = p * u + 1.0f / 120.0f;
  p = p * u + 1.0f / 24.0f;
  p = p * u + 1.0f / 6.0f;
  p = p * u + 0.5f;
  p = p * u + 1.0f;
  p = p * u + 1.0f;
  return p;
}

// e^x for x <= 0 (positive x is taken as 0). Returns 0 below -87, where e^x would no longer be
// a normal float, and for NaN.
inline float fast_exp(float x) {
  if (!(x > -87.0f)) return 0.0f;
  if (x > 0.0f) x = 0.0f;
  // e^x = 2^i e^u with i = round(x / ln 2) and u = x - i ln 2 in [-ln 2 / 2, ln 2 / 2], taken
  // in two parts (Cody and Waite) so u keeps its precision; e^u by exp_series.
  const int32_t i = int32_t(x * 1.44269504088896341f - 0.5f);  // x <= 0: rounds to nearest
  const float u = (x - float(i) * 0.693145751953125f) - float(i) * 1.42860682030941723e-6f;
  const float p = exp_series(u);
  const uint32_t bits = uint32_t(i + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

#if defined(__SSE2__)
// fast_exp on four lanes, with the same operations in the same order: each lane is bit for bit
// fast_exp of that lane.
inline __m128 fast_exp4(__m128 x) {
  const __m128 lowest = _mm_set1_ps(-87.0f);
  const __m128 valid = _mm_cmpgt_ps(x, lowest);  // false for NaN and x <= -87: result 0
  x = _mm_max_ps(_mm_min_ps(x, _mm_setzero_ps()), lowest);
  const __m128i i = _mm_cvttps_epi32(
      _mm_sub_ps(_mm_mul_ps(x, _mm_set1_ps(1.44269504088896341f)), _mm_set1_ps(0.5f)));
  const __m128 fi = _mm_cvtepi32_ps(i);
  const __m128 u = _mm_sub_ps(_mm_sub_ps(x, _mm_mul_ps(fi, _mm_set1_ps(0.693145751953125f))),
                              _mm_mul_ps(fi, _mm_set1_ps(1.42860682030941723e-6f)));
  const __m128 p = exp_series(u);  // __m128 is a GCC/Clang vector of floats
  const __m128i bits = _mm_slli_epi32(_mm_add_epi32(i, _mm_set1_epi32(127)), 23);
  return _mm_and_ps(_mm_mul_ps(p, _mm_castsi128_ps(bits)), valid);
}
#endif

}  // namespace afr
