#include <afr/common/image.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <cstring>

namespace afr {
namespace {

double linear_to_srgb_exact(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

}  // namespace

// ---- sRGB transfer function (IEC 61966-2-1) ----

float srgb_to_linear(float c) {
  const double v = c;
  return float(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
}

float linear_to_srgb(float c) { return float(linear_to_srgb_exact(c)); }

namespace {

// The 8-bit code of a linear value in (0, 1) by the formula: one pow per call.
uint8_t srgb8_by_formula(float c) { return uint8_t(std::lround(linear_to_srgb_exact(c) * 255.0)); }

// The code is a step function of c: thresholds[k] is the smallest positive float whose code is
// at least k (k = 1..255), found once by bisection over the ordered float bit patterns, so
// that a lookup gives the formula's code for every float, with 8 comparisons instead of a pow.
struct Srgb8Thresholds {
  std::array<float, 256> thresholds{};
  Srgb8Thresholds() {
    for (int k = 1; k < 256; ++k) {
      // Positive floats order like their bit patterns; the code of 1.0f's predecessor is 255.
      uint32_t lo = 0, hi = 0x3f800000u;  // code(lo) < k <= code(hi) (0 and 1.0f)
      while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        float v;
        std::memcpy(&v, &mid, sizeof v);
        (srgb8_by_formula(v) >= k ? hi : lo) = mid;
      }
      std::memcpy(&thresholds[size_t(k)], &hi, sizeof(float));
    }
  }
};

}  // namespace

uint8_t linear_to_srgb8(float c) {
  if (!(c > 0.0f)) return 0;  // also NaN
  if (c >= 1.0f) return 255;
  static const Srgb8Thresholds table;
  const float* t = table.thresholds.data();
  int code = 0;  // the largest k with t[k] <= c: binary search over 1..255
  for (int step = 128; step > 0; step /= 2) {
    if (code + step <= 255 && t[code + step] <= c) code += step;
  }
  return uint8_t(code);
}

// ---- Error metric ----

double rms_error_255(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.pixels.size() != b.pixels.size()) {
    throw Error(fmt::format("cannot compare images of different sizes: {} x {} and {} x {}",
                            a.width, a.height, b.width, b.height));
  }
  if (a.pixels.empty()) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double d = double(linear_to_srgb8(a.pixels[i][c])) - linear_to_srgb8(b.pixels[i][c]);
      sum += d * d;
    }
  }
  return std::sqrt(sum / (3.0 * double(a.pixels.size())));
}

}  // namespace afr
