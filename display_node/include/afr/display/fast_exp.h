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
  // e^x = 2^t = 2^i * 2^f with i = round(t), f in [-0.5, 0.5]; 2^f = e^(f ln 2) by its Taylor
  // series to degree 6 (remainder (0.5 ln 2)^7 / 7! < 1.3e-7).
  const float t = x * 1.44269504088896341f;
  const int32_t i = int32_t(t - 0.5f);  // t <= 0: rounds to nearest
  const float u = (t - float(i)) * 0.693147180559945309f;
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
