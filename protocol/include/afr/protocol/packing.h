// The compact number formats of a packed sample (docs/protocol.md, "Sample batch"): image
// positions as 24-bit fixed point, colors as shared-exponent RGB9E5, velocities as IEEE half
// floats. Inline because the batch codec calls them once per sample; they allocate nothing and
// never produce a NaN or an Inf.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace afr::protocol {

// ---------------------------------------------------------------------------------------------
// Image positions: unsigned 15.9 fixed point in 24 bits

// 2^15 = 32768 pixels at 1/512 pixel. Encoding floors, so a position stays in its 1/512 bin
// and hence in its pixel; decoding returns the bin's center where a float can hold it (below
// 16384 px: error <= 1/1024 px) and the bin's start above, where floats are themselves spaced
// 1/512 px apart, so there the round trip of a float is exact.
inline constexpr int kPositionFractionBits = 9;
inline constexpr uint32_t kPositionScale = 1u << kPositionFractionBits;  // steps per pixel
inline constexpr uint32_t kMaxPositionCode = (1u << 24) - 1;

// x must be finite and in [0, 32768); anything else is clamped into the range.
inline uint32_t encode_position(float x) {
  if (!(x > 0.0f)) return 0;                       // also NaN
  const float scaled = x * float(kPositionScale);  // exact: a power-of-two scale
  if (!(scaled < float(kMaxPositionCode + 1))) return kMaxPositionCode;
  return uint32_t(scaled);  // truncation is floor for x >= 0
}

inline float decode_position(uint32_t code) {
  // 2 * code + 1 < 2^24 below 2^23: the bin center is exact. Above, a float cannot hold it.
  if (code < (1u << 23)) return float(2 * code + 1) * (1.0f / float(2 * kPositionScale));
  return float(code) * (1.0f / float(kPositionScale));
}

// ---------------------------------------------------------------------------------------------
// Colors: RGB9E5 (EXT_texture_shared_exponent): 9-bit mantissas, a shared 5-bit exponent

// Bits 0-8 red, 9-17 green, 18-26 blue, 27-31 exponent. Range [0, 65408]; the largest channel
// keeps a relative error <= 2^-9, the others an absolute error <= half the largest channel's
// step. Negative values and NaN become 0; values above the range and +Inf become 65408.
inline constexpr float kRgb9e5Max = 65408.0f;  // (511 / 512) * 2^16

namespace detail {
// 2^e for e in [-126, 127], exactly.
inline float exp2i(int e) { return std::bit_cast<float>(uint32_t(e + 127) << 23); }
inline float clamp_rgb9e5_channel(float c) {
  return c > 0.0f ? std::min(c, kRgb9e5Max) : 0.0f;  // NaN fails c > 0
}
}  // namespace detail

inline uint32_t encode_rgb9e5(float r, float g, float b) {
  r = detail::clamp_rgb9e5_channel(r);
  g = detail::clamp_rgb9e5_channel(g);
  b = detail::clamp_rgb9e5_channel(b);
  const float max_c = std::max(r, std::max(g, b));
  // floor(log2(max_c)) from the float's exponent field; zero and denormals give -127.
  const int floor_log2 = int((std::bit_cast<uint32_t>(max_c) >> 23) & 0xff) - 127;
  int exp_shared = std::max(-16, floor_log2) + 1 + 15;  // in [0, 31]
  // Step of the mantissas: 2^(exp_shared - 15 - 9). Rounding in double is exact (a float
  // times a power of two plus 0.5 fits 53 bits), so this is the specification's floor(x + 0.5).
  double inv_step = double(detail::exp2i(24 - exp_shared));
  const uint32_t max_m = uint32_t(double(max_c) * inv_step + 0.5);
  if (max_m == 512) {  // rounding carried into a tenth bit
    ++exp_shared;
    inv_step *= 0.5;
  }
  const uint32_t rm = uint32_t(double(r) * inv_step + 0.5);
  const uint32_t gm = uint32_t(double(g) * inv_step + 0.5);
  const uint32_t bm = uint32_t(double(b) * inv_step + 0.5);
  return rm | (gm << 9) | (bm << 18) | (uint32_t(exp_shared) << 27);
}

struct Rgb {
  float r, g, b;
};

inline Rgb decode_rgb9e5(uint32_t v) {
  const float step = detail::exp2i(int(v >> 27) - 24);
  return {float(v & 0x1ff) * step, float((v >> 9) & 0x1ff) * step, float((v >> 18) & 0x1ff) * step};
}

// ---------------------------------------------------------------------------------------------
// Velocities: IEEE 754 binary16, round to nearest even

inline constexpr float kHalfMax = 65504.0f;

// Values beyond +-65504 (and +-Inf) saturate to +-65504; NaN becomes 0. So the result is
// always finite.
inline uint16_t encode_half(float f) {
  if (std::isnan(f)) return 0;
  f = std::clamp(f, -kHalfMax, kHalfMax);
  const uint32_t bits = std::bit_cast<uint32_t>(f);
  const uint16_t sign = uint16_t((bits >> 16) & 0x8000);
  const uint32_t abs = bits & 0x7fffffff;
  if (abs < 0x38800000) {  // below 2^-14: a half denormal (or zero)
    // abs as a float times 2^24 gives the denormal's integer mantissa; round to nearest even
    // through the float unit: adding 0.5f (2^-1) aligns the result's ulp with the half's.
    const float a = std::bit_cast<float>(abs) + 0.5f;
    return uint16_t(sign | uint16_t(std::bit_cast<uint32_t>(a) - 0x3f000000u));
  }
  // Normal: rebias the exponent (127 -> 15) and round the 23-bit mantissa to 10 bits.
  const uint32_t odd = (abs >> 13) & 1;
  const uint32_t rounded = abs + 0xfff + odd - ((127 - 15) << 23);
  return uint16_t(sign | uint16_t(rounded >> 13));
}

inline float decode_half(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000) << 16;
  const uint32_t exp = (h >> 10) & 0x1f;
  const uint32_t mant = h & 0x3ff;
  if (exp == 0) {  // zero or denormal: mant * 2^-24
    const float v = float(mant) * (1.0f / 16777216.0f);
    return std::bit_cast<float>(std::bit_cast<uint32_t>(v) | sign);
  }
  if (exp == 31) {  // Inf or NaN: never produced by encode_half; decoders reject them first
    return std::bit_cast<float>(sign | 0x7f800000u | (mant << 13));
  }
  return std::bit_cast<float>(sign | ((exp + 127 - 15) << 23) | (mant << 13));
}

// True when a half is Inf or NaN.
inline bool half_is_special(uint16_t h) { return (h & 0x7c00) == 0x7c00; }

}  // namespace afr::protocol
