// A fast exp for the reconstruction filter's Gaussians: the CPU backend evaluates several per
// sample, and std::exp would take most of a frame. Accurate to about 2e-7 relative, which is
// far below the 1/255 steps of a display and below the differences of GPU exp implementations.
#pragma once

#include <cstdint>
#include <cstring>

namespace afr {

// e^x for x <= 0 (positive x is taken as 0). Returns 0 below -87, where e^x would no longer be
// a normal float, and for NaN.
inline float fast_exp(float x) {
  if (!(x > -87.0f)) return 0.0f;
  if (x > 0.0f) x = 0.0f;
  // e^x = 2^i e^u with i = round(x / ln 2) and u = x - i ln 2 in [-ln 2 / 2, ln 2 / 2], taken
  // in two parts (Cody and Waite) so u keeps its precision; e^u by its Taylor series to
  // degree 6 (remainder (ln 2 / 2)^7 / 7! < 1.3e-7).
  const int32_t i = int32_t(x * 1.44269504088896341f - 0.5f);  // x <= 0: rounds to nearest
  const float u = (x - float(i) * 0.693145751953125f) - float(i) * 1.42860682030941723e-6f;
  float p = 1.0f / 720.0f;
  p = p * u + 1.0f / 120.0f;
  p = p * u + 1.0f / 24.0f;
  p = p * u + 1.0f / 6.0f;
  p = p * u + 0.5f;
  p = p * u + 1.0f;
  p = p * u + 1.0f;
  const uint32_t bits = uint32_t(i + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

}  // namespace afr
